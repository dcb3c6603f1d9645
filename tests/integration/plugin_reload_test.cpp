// A plugin reloaded in a running development rcand (issue 20; docs/protocol.md §7.15): POST
// /api/plugins/<id>/reload and `rcanctl plugins reload ID` halt every motor (the e-stop latches), hold the plugin's
// routes at 503 while calls already admitted finish, and serve the version now on disk; a failing reload leaves the
// plugin in a named failed state; without runtime.plugins.allow_reload the request is refused and nothing stops.
#include <doctest/doctest.h>

#include <filesystem>
#include <fstream>
#include <future>
#include <thread>

#include "eventually.hpp"
#include "rcand_process.hpp"
#include "temp_dir.hpp"

using namespace rcand::test;
using nlohmann::json;
using namespace std::chrono_literals;

namespace {

constexpr const char* kReloadId = "org.rcand.test.reload";
const std::string kReloadPath = std::string("/api/plugins/") + kReloadId + "/reload";
const std::string kVersionPath = std::string("/api/cap/") + kReloadId + "/version";

// Puts build variant `variant` (1 or 2) of the reload fixture into `folder` as the plugin rcand loads, under a
// manifest that says `version` (and, `isolated`, that its capability runs in a process of its own). The library is
// replaced by a rename, as a build or a package install does.
void install_reload_fixture(const std::filesystem::path& folder, int variant, const std::string& version, bool isolated = false) {
  std::filesystem::create_directories(folder);
  const auto built = test_plugin_dir() / "reload" / ("rcand_test_reload_v" + std::to_string(variant) + ".so");
  std::filesystem::copy_file(built, folder / "incoming.so", std::filesystem::copy_options::overwrite_existing);
  std::filesystem::rename(folder / "incoming.so", folder / "rcand_test_reload.so");
  std::ofstream(folder / "reload.json")
      << json{{"id", kReloadId},
              {"version", version},
              {"library", "rcand_test_reload.so"},
              {"abi", {{"major", 1}, {"minor", 0}}},
              {"provides", json::array({isolated ? json{{"kind", "capability"}, {"name", kReloadId}, {"isolation", "process"}}
                                                 : json{{"kind", "capability"}, {"name", kReloadId}}})}}
             .dump();
}

json reload_config(bool allow) {
  auto config = sim_config();
  config["rcan_protocol"]["capabilities"].push_back(kReloadId);
  if (allow) config["runtime"]["plugins"] = {{"allow_reload", true}};
  return config;
}

std::string served_version(const RcandProcess& rcand, int* status = nullptr) {
  const json body = rcand.json("GET", kVersionPath, "user-token", {}, status);
  return body.value("version", "");
}

}  // namespace

TEST_CASE("plugin reload: motors halt first, the new version on disk is served, the request is audited") {
  TempDir dir;
  const auto folder = dir.path() / "plugins";
  install_reload_fixture(folder, 1, "1.0.0");
  RcandProcess rcand(reload_config(true), {plugin_dir(), folder});
  REQUIRE(served_version(rcand) == "1.0.0");
  int status = 0;
  rcand.json("POST", "/api/action", "user-token", R"({"type":"move","linear":0.3,"angular":0,"duration_ms":5000})", &status);
  REQUIRE(status == 200);
  REQUIRE(drive_status(rcand)["moving"] == true);

  const std::string added_path = std::string("/api/cap/") + kReloadId + "/added";
  CHECK(rcand.request("GET", added_path, "user-token").status == 404);

  install_reload_fixture(folder, 2, "2.0.0");
  const json answer = rcand.json("POST", kReloadPath, "owner-token", {}, &status);
  REQUIRE(status == 200);
  CHECK(answer["plugin"] == kReloadId);
  CHECK(answer["state"] == "loaded");
  CHECK(answer["version"] == "2.0.0");
  CHECK(answer["estopped"] == true);
  CHECK(answer["motors_stopped"] == true);
  REQUIRE(answer["instances"].size() == 1);
  CHECK(answer["instances"][0]["state"] == "running");
  CHECK(drive_status(rcand)["moving"] == false);
  const json estop = rcand.json("GET", "/api/estop", "guest-token");
  CHECK(estop["estopped"] == true);
  CHECK(estop["reason"].get<std::string>().find("plugin reload") != std::string::npos);
  CHECK(served_version(rcand) == "2.0.0");
  CHECK(rcand.json("GET", added_path, "user-token")["added"] == true);  // a route only the new version has
  const json plugins = rcand.json("GET", "/api/plugins", "owner-token");
  for (const auto& plugin : plugins["plugins"])
    if (plugin["id"] == kReloadId) CHECK(plugin["version"] == "2.0.0");

  bool audited = false;
  const json audit = rcand.json("GET", "/api/audit?limit=50", "owner-token");
  INFO(audit.dump());
  for (const auto& entry : audit["entries"]) audited = audited || entry.value("event", "").find(kReloadPath) != std::string::npos;
  CHECK(audited);

  // Who may, and what: config scope; an unknown plugin is 404.
  CHECK(rcand.request("POST", kReloadPath, "user-token").status == 403);
  const json unknown = rcand.json("POST", "/api/plugins/org.nobody/reload", "owner-token", {}, &status);
  CHECK(status == 404);
  CHECK(unknown["code"] == "NOT_FOUND");
  CHECK(rcand.json("POST", "/api/plugins/" + std::string(kReloadId) + "/restart", "owner-token", {}, &status)["code"] ==
        "NOT_FOUND");
}

TEST_CASE("plugin reload: an isolated capability's new version is served by a new process; rcand maps neither") {
  TempDir dir;
  const auto folder = dir.path() / "plugins";
  install_reload_fixture(folder, 1, "1.0.0", /*isolated=*/true);
  RcandProcess rcand(reload_config(true), {plugin_dir(), folder});
  REQUIRE(served_version(rcand) == "1.0.0");
  const auto host_pid = [&] {
    return rcand.json("GET", "/api/status", "owner-token")["capabilities"][kReloadId]["status"]["process"].value("pid", 0);
  };
  const auto rcand_maps_the_plugin = [&] {
    std::ifstream maps("/proc/" + std::to_string(rcand.pid()) + "/maps");
    const std::string text((std::istreambuf_iterator<char>(maps)), std::istreambuf_iterator<char>());
    return text.find("rcand_test_reload") != std::string::npos;
  };
  const int first = host_pid();
  REQUIRE(first > 0);
  CHECK(!rcand_maps_the_plugin());

  install_reload_fixture(folder, 2, "2.0.0", /*isolated=*/true);
  int status = 0;
  const json answer = rcand.json("POST", kReloadPath, "owner-token", {}, &status);
  INFO(answer.dump());
  REQUIRE(status == 200);
  CHECK(answer["version"] == "2.0.0");
  CHECK(answer["instances"][0]["state"] == "running");
  CHECK(served_version(rcand) == "2.0.0");
  CHECK(rcand.json("GET", std::string("/api/cap/") + kReloadId + "/added", "user-token")["added"] == true);
  CHECK(eventually([&] { return host_pid() != first && host_pid() > 0; }, 5s));  // the status board catches up
  CHECK(!rcand_maps_the_plugin());  // before this, a reload opened the library in rcand
}

TEST_CASE("plugin reload: a driver plugin's new object takes the actuator's slot; the old one is halted and never used again") {
  auto config = sim_config();
  config["runtime"]["plugins"] = {{"allow_reload", true}};
  RcandProcess rcand(config, {plugin_dir()});
  int status = 0;
  rcand.json("POST", "/api/action", "user-token", R"({"type":"move","linear":0.3,"angular":0,"duration_ms":5000})", &status);
  REQUIRE(status == 200);
  REQUIRE(drive_status(rcand)["moving"] == true);
  REQUIRE(drive_status(rcand)["commands"].get<int>() > 0);

  const json answer = rcand.json("POST", "/api/plugins/org.rcand.sim_drive/reload", "owner-token", {}, &status);
  INFO(answer.dump());
  REQUIRE(status == 200);
  CHECK(answer["estopped"] == true);
  CHECK(answer["motors_stopped"] == true);
  CHECK(answer["instances"] == json::array({{{"driver", "drive0"}, {"state", "running"}}}));
  const json fresh = drive_status(rcand);  // a new object: nothing commanded it yet
  CHECK(fresh["moving"] == false);
  CHECK(fresh["commands"] == 0);
  CHECK(rcand.json("GET", "/api/drivers/drive0", "owner-token")["state"] == "ok");

  // The new object serves the gate and the stop path.
  rcand.json("POST", "/api/action", "user-token", R"({"type":"move","linear":0.3,"angular":0,"duration_ms":5000})", &status);
  CHECK(status == 423);  // the reload's stop stays latched until an operator clears it
  REQUIRE(rcand.request("POST", "/api/estop/clear", "owner-token").status == 200);
  rcand.json("POST", "/api/action", "user-token", R"({"type":"move","linear":0.3,"angular":0,"duration_ms":5000})", &status);
  CHECK(status == 200);
  CHECK(drive_status(rcand)["moving"] == true);
  REQUIRE(rcand.request("POST", "/api/stop", "user-token").status == 200);
  CHECK(drive_status(rcand)["moving"] == false);
  CHECK(drive_status(rcand)["halts"].get<int>() >= 1);

  // A plugin with a driver and a capability (the Acme gripper): both restart, the capability commands the new driver.
  const json gripper = rcand.json("POST", "/api/plugins/com.acme.gripper/reload", "owner-token", {}, &status);
  INFO(gripper.dump());
  REQUIRE(status == 200);
  CHECK(gripper["instances"] == json::array({{{"driver", "gripper0"}, {"state", "running"}},
                                             {{"capability", "com.acme.gripper"}, {"state", "running"}}}));
  REQUIRE(rcand.request("POST", "/api/estop/clear", "owner-token").status == 200);
  rcand.json("POST", "/api/cap/com.acme.gripper/grip", "user-token", R"({"state":"close"})", &status);
  CHECK(status == 200);

  const auto table = run_tool(rcanctl_binary(), {"plugins", "reload", "org.rcand.sim_drive", "--port",
                                                 std::to_string(rcand.port()), "--token", "owner-token"});
  CHECK(table.exit_code == 0);
  CHECK(table.out.find("driver") != std::string::npos);
  CHECK(table.out.find("drive0") != std::string::npos);
}

TEST_CASE("plugin reload: a driver with a call that does not return in time keeps its slot; the reload fails, named") {
  auto config = sim_config();
  config["runtime"]["plugins"] = {{"allow_reload", true}};
  config["drivers"][0]["halt_delay_ms"] = 4000;  // the reload's own stop is inside halt() for 4 s; retire waits 2 s
  RcandProcess rcand(config, {plugin_dir()});
  int status = 0;
  const json answer = rcand.json("POST", "/api/plugins/org.rcand.sim_drive/reload", "owner-token", {}, &status);
  INFO(answer.dump());
  CHECK(status == 500);
  CHECK(answer["code"] == "RELOAD_FAILED");
  CHECK(answer["error"].get<std::string>().find("did not finish") != std::string::npos);
  REQUIRE(answer["instances"].size() == 1);
  CHECK(answer["instances"][0]["driver"] == "drive0");
  CHECK(answer["instances"][0]["state"] == "failed");
  const json driver = rcand.json("GET", "/api/drivers/drive0", "owner-token");
  CHECK(driver["state"] == "failed");
  CHECK(answer["motors_stopped"] == false);  // the halt was still running when the stop answered
  CHECK(rcand.json("GET", "/api/estop", "guest-token")["estopped"] == true);
  // The old object is back in the slot: its halt finishes, and the next stop's halt reaches it again.
  const auto halts = [&] { return drive_status(rcand).value("halts", -1); };
  CHECK(eventually([&] { return halts() == 1; }, 20s, 50ms));
  REQUIRE(rcand.request("POST", "/api/stop", "user-token").status == 200);
  CHECK(eventually([&] { return halts() == 2; }, 20s, 50ms));
}

TEST_CASE("plugin reload: a failing reload leaves a named failed state and the robot stopped; fixed, it serves again") {
  TempDir dir;
  const auto folder = dir.path() / "plugins";
  install_reload_fixture(folder, 1, "1.0.0");
  RcandProcess rcand(reload_config(true), {plugin_dir(), folder});
  REQUIRE(served_version(rcand) == "1.0.0");

  install_reload_fixture(folder, 2, "3.0.0");  // the manifest and the library disagree
  int status = 0;
  const json failed = rcand.json("POST", kReloadPath, "owner-token", {}, &status);
  CHECK(status == 500);
  CHECK(failed["code"] == "RELOAD_FAILED");
  CHECK(failed["state"] == "manifest-mismatch");
  CHECK(failed["error"].get<std::string>().find("manifest-mismatch") != std::string::npos);
  CHECK(failed["estopped"] == true);
  served_version(rcand, &status);
  CHECK(status == 503);  // out of service, not a crash
  CHECK(rcand.json("GET", "/health")["status"] == "ok");
  CHECK(rcand.json("GET", "/api/estop", "guest-token")["estopped"] == true);

  install_reload_fixture(folder, 2, "2.0.0");
  const json fixed = rcand.json("POST", kReloadPath, "owner-token", {}, &status);
  CHECK(status == 200);
  CHECK(fixed["state"] == "loaded");
  CHECK(served_version(rcand) == "2.0.0");
}

TEST_CASE("plugin reload: a call in flight finishes on the old version; calls meanwhile get 503") {
  TempDir dir;
  const auto folder = dir.path() / "plugins";
  install_reload_fixture(folder, 1, "1.0.0");
  RcandProcess rcand(reload_config(true), {plugin_dir(), folder});
  const auto entered = dir.path() / "entered", release = dir.path() / "release";

  auto in_flight = std::async(std::launch::async, [&] {
    int status = 0;
    const json body = rcand.json(
        "GET", std::string("/api/cap/") + kReloadId + "/hold?entered=" + entered.string() + "&release=" + release.string(),
        "user-token", {}, &status);
    return std::make_pair(status, body);
  });
  const auto deadline = std::chrono::steady_clock::now() + 10s;
  while (!std::filesystem::exists(entered) && std::chrono::steady_clock::now() < deadline) std::this_thread::sleep_for(5ms);
  REQUIRE(std::filesystem::exists(entered));

  install_reload_fixture(folder, 2, "2.0.0");
  auto reload = std::async(std::launch::async, [&] {
    int status = 0;
    const json body = rcand.json("POST", kReloadPath, "owner-token", {}, &status);
    return std::make_pair(status, body);
  });
  // The reload waits for the held call; until it is released, a new call is held out with 503. A probe admitted
  // before the gate closed queues behind the held call (one handler at a time): it is left to finish after the
  // release, and the next probe is sent.
  std::vector<std::future<int>> probes;
  bool held_out = false;
  while (!held_out && std::chrono::steady_clock::now() < deadline) {
    probes.push_back(std::async(std::launch::async, [&] {
      int status = 0;
      served_version(rcand, &status);
      return status;
    }));
    if (probes.back().wait_for(200ms) != std::future_status::ready) continue;  // admitted: queued behind the held call
    held_out = probes.back().get() == 503;
    probes.pop_back();
  }
  CHECK(held_out);
  CHECK(reload.wait_for(0ms) == std::future_status::timeout);
  std::ofstream(release) << "go\n";

  const auto held = in_flight.get();  // (status, body); no structured bindings inside doctest macros
  CHECK(held.first == 200);
  CHECK(held.second["version"] == "1.0.0");  // finished on the code it started on
  CHECK(held.second["released"] == true);
  const auto reloaded = reload.get();
  CHECK(reloaded.first == 200);
  CHECK(reloaded.second["version"] == "2.0.0");
  for (auto& probe : probes) CHECK(probe.get() != 0);  // each queued probe got an answer, whichever
  CHECK(served_version(rcand) == "2.0.0");
}

TEST_CASE("plugin reload: refused (409 RELOAD_DISABLED) without runtime.plugins.allow_reload; nothing stops") {
  TempDir dir;
  const auto folder = dir.path() / "plugins";
  install_reload_fixture(folder, 1, "1.0.0");
  RcandProcess rcand(reload_config(false), {plugin_dir(), folder});
  install_reload_fixture(folder, 2, "2.0.0");
  int status = 0;
  const json refused = rcand.json("POST", kReloadPath, "owner-token", {}, &status);
  CHECK(status == 409);
  CHECK(refused["code"] == "RELOAD_DISABLED");
  CHECK(refused["error"].get<std::string>().find("runtime.plugins.allow_reload") != std::string::npos);
  CHECK(rcand.json("GET", "/api/estop", "guest-token")["estopped"] == false);
  CHECK(served_version(rcand) == "1.0.0");

  const auto port = std::to_string(rcand.port());
  const auto refused_cli = run_tool(rcanctl_binary(), {"plugins", "reload", kReloadId, "--port", port, "--token", "owner-token"});
  CHECK(refused_cli.exit_code == 1);
  CHECK(refused_cli.err.find("RELOAD_DISABLED") != std::string::npos);
  CHECK(run_tool(rcanctl_binary(), {"plugins", "reload", "--port", port, "--token", "owner-token"}).exit_code == 2);
}

TEST_CASE("rcanctl plugins reload: a table, or JSON with --json; exit 0 when reloaded, 1 when the robot refuses") {
  TempDir dir;
  const auto folder = dir.path() / "plugins";
  install_reload_fixture(folder, 1, "1.0.0");
  RcandProcess rcand(reload_config(true), {plugin_dir(), folder});
  const auto port = std::to_string(rcand.port());
  install_reload_fixture(folder, 2, "2.0.0");

  const auto table = run_tool(rcanctl_binary(), {"plugins", "reload", kReloadId, "--port", port, "--token", "owner-token"});
  CHECK(table.exit_code == 0);
  CHECK(table.out.find("2.0.0") != std::string::npos);
  CHECK(table.out.find("running") != std::string::npos);
  CHECK(table.out.find("rcanctl estop clear") != std::string::npos);

  const auto as_json =
      run_tool(rcanctl_binary(), {"plugins", "reload", kReloadId, "--port", port, "--token", "owner-token", "--json"});
  CHECK(as_json.exit_code == 0);
  const json parsed = json::parse(as_json.out, nullptr, false);
  CHECK(parsed["version"] == "2.0.0");
  CHECK(parsed["state"] == "loaded");

  const auto unknown = run_tool(rcanctl_binary(), {"plugins", "reload", "org.nobody", "--port", port, "--token", "owner-token"});
  CHECK(unknown.exit_code == 1);
  CHECK(run_tool(rcanctl_binary(), {"plugins", "reload", "--help"}).exit_code == 0);
}

TEST_CASE("plugin reload: bounded - past the limit a reload is refused (409 RELOAD_LIMIT) before anything stops") {
  TempDir dir;
  const auto folder = dir.path() / "plugins";
  install_reload_fixture(folder, 1, "1.0.0");
  RcandProcess rcand(reload_config(true), {plugin_dir(), folder});
  int status = 0;
  for (int i = 0; i < 16; ++i) {  // PluginHost::kMaxReopens: each reload keeps its old image mapped for good
    rcand.json("POST", kReloadPath, "owner-token", {}, &status);
    REQUIRE(status == 200);
  }
  REQUIRE(rcand.request("POST", "/api/estop/clear", "owner-token").status == 200);
  const json refused = rcand.json("POST", kReloadPath, "owner-token", {}, &status);
  CHECK(status == 409);
  CHECK(refused["code"] == "RELOAD_LIMIT");
  CHECK(refused["error"].get<std::string>().find("restart rcand") != std::string::npos);
  CHECK(refused["estopped"] == false);  // nothing was stopped for it
  CHECK(rcand.json("GET", "/api/estop", "guest-token")["estopped"] == false);
  CHECK(served_version(rcand) == "1.0.0");  // the version it had still serves
  // The private reload directory is in the state dir, and empty: every copy was unlinked once mapped.
  std::size_t private_dirs = 0;
  for (const auto& entry : std::filesystem::directory_iterator(rcand.dir().path() / "state"))
    if (entry.path().filename().string().starts_with("plugin-reload-")) {
      ++private_dirs;
      CHECK(std::filesystem::is_empty(entry.path()));
    }
  CHECK(private_dirs == 1);
}
