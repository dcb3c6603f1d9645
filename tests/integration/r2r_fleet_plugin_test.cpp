// The auctions as a plugin (org.rcand.fleet) in a real rcand: running on robots with runtime.r2r.enabled and only
// there, advertised when the file lists it or its capabilities are auto-detected (issue 30), a robot without it answers the
// auction endpoints 503 naming it and keeps speaking R2R, and a vendor plugin's R2rLink::set_cost_function (SDK 1.0) still prices
// the bids.
#include <doctest/doctest.h>

#include <algorithm>
#include <filesystem>
#include <optional>
#include <string>

#include "r2r_lab.hpp"
#include "rcand_process.hpp"
#include "ws_client.hpp"

using namespace rcand::test;
using nlohmann::json;

namespace {

constexpr const char* kFleet = "org.rcand.fleet";

bool lists(const json& capabilities, const std::string& name) {
  return std::find(capabilities.begin(), capabilities.end(), name) != capabilities.end();
}

// The in-tree plugin directory without the fleet plugin: a robot where it is not installed.
std::filesystem::path plugins_without_fleet(const TempDir& dir) {
  const auto folder = dir.path() / "plugins-without-fleet";
  std::filesystem::create_directories(folder);
  for (const auto& entry : std::filesystem::directory_iterator(plugin_dir())) {
    const std::string name = entry.path().filename().string();
    if (!entry.is_regular_file() || name == "fleet.json" || name == "rcand_fleet.so") continue;
    std::filesystem::create_symlink(entry.path(), folder / name);
  }
  return folder;
}

// A task at (9, 9) for a robot with teleop, sent by `peer`: this robot's bid, or nullopt.
std::optional<json> bid_on(WsClient& peer, const std::string& message_id, const std::string& task_id) {
  peer.send(r2r_message(message_id, "task_request",
                        {{"task_id", task_id},
                         {"required_capabilities", {"teleop"}},
                         {"location", {{"x", 9.0}, {"y", 9.0}}},
                         {"bid_deadline", unix_now() + 10}}));
  return read_until(peer, [](const json& m) { return m.value("type", "") == "negotiation"; });
}

}  // namespace

TEST_CASE("fleet plugin: runs when runtime.r2r.enabled is true; advertised as the file declares (issue 30)") {
  TempDir dir;
  const auto token = dir.write("r2r.token", "owner-token\n");
  // A written list that does not name it: it runs, and the three advertisements are the list as written.
  const auto written = r2r_robot_config("alpha", token);
  RcandProcess r2r_robot(written);
  const json declared = written["rcan_protocol"]["capabilities"];
  CHECK_FALSE(lists(declared, kFleet));
  json expected = json::array({"status"});
  for (const auto& name : declared)
    if (name != "status") expected.push_back(name);
  const json discovery = r2r_robot.json("GET", "/api/discovery");
  CHECK(discovery["capabilities"] == expected);
  CHECK(discovery["txt_record"]["caps"] == [&] {
    std::string caps;
    for (const auto& name : expected) caps += (caps.empty() ? "" : ",") + name.get<std::string>();
    return caps;
  }());
  CHECK(r2r_robot.json("GET", "/api/status", "guest-token")["capabilities"][kFleet]["state"] != "failed");

  auto listed = r2r_robot_config("bravo", token);
  listed["rcan_protocol"]["capabilities"].push_back(kFleet);  // listed: advertised, once
  RcandProcess explicit_robot(listed);
  const json caps = explicit_robot.json("GET", "/api/discovery")["capabilities"];
  CHECK(std::count(caps.begin(), caps.end(), kFleet) == 1);

  auto detected = r2r_robot_config("charlie", token);
  detected["rcan_protocol"].erase("capabilities");  // auto-detected (§9.3): it declares itself
  RcandProcess detected_robot(detected);
  CHECK(lists(detected_robot.json("GET", "/api/discovery")["capabilities"], kFleet));

  RcandProcess plain(sim_config());  // no R2R: no auctions, and nothing declared for them
  CHECK_FALSE(lists(plain.json("GET", "/api/discovery")["capabilities"], kFleet));
}

TEST_CASE("fleet plugin missing: the auction endpoints answer 503 naming it; the rest of R2R works") {
  TempDir dir;
  const auto token = dir.write("r2r.token", "owner-token\n");
  RcandProcess robot(r2r_robot_config("alpha", token), {plugins_without_fleet(dir)});
  CHECK_FALSE(lists(robot.json("GET", "/api/discovery")["capabilities"], kFleet));

  int status = 0;
  const json refused = robot.json("POST", "/api/r2r/auction", "user-token", json{{"task_id", "T1"}}.dump(), &status);
  CHECK(status == 503);
  CHECK(refused["code"] == "UNAVAILABLE");
  CHECK(refused["plugin"] == kFleet);
  CHECK(refused["error"].get<std::string>().find(kFleet) != std::string::npos);
  robot.json("GET", "/api/r2r/auction/T1", "guest-token", "", &status);
  CHECK(status == 503);

  const json peers = robot.json("GET", "/api/r2r/peers", "guest-token", "", &status);
  CHECK(status == 200);
  CHECK(peers["held_tasks"] == json::array());
  robot.json("POST", "/api/r2r/send", "user-token", json{{"type", "status"}, {"payload", {{"battery", 50}}}}.dump(), &status);
  CHECK(status == 200);
  WsClient peer;  // its status says nothing of held tasks: nothing here holds any
  REQUIRE(peer.connect(robot.port(), "user-token") == 101);
  const auto heard = read_until(peer, [](const json& m) { return m.value("type", "") == "status"; });
  REQUIRE(heard);
  CHECK_FALSE((*heard)["payload"].contains("tasks_held"));
  CHECK(robot.json("GET", "/health")["status"] == "ok");
}

TEST_CASE("fleet plugin: a vendor's R2rLink::set_cost_function prices this robot's bids") {
  TempDir dir;
  const auto token = dir.write("r2r.token", "owner-token\n");
  auto config = r2r_robot_config("alpha", token);
  config["rcan_protocol"]["capabilities"].push_back("org.rcand.test.pricing");  // starts before the fleet plugin
  RcandProcess robot(config, {plugin_dir(), test_plugin_dir() / "pricing"});
  WsClient peer;
  REQUIRE(peer.connect(robot.port(), "user-token") == 101);
  const auto bid = bid_on(peer, "req-1", "P1");
  REQUIRE(bid);
  CHECK((*bid)["payload"]["cost"] == 12.5);
  // The fleet plugin publishes what it holds (GET /api/status); nothing yet: the requester has not awarded.
  CHECK(poll_until<bool>([&]() -> std::optional<bool> {
    const json fleet = robot.json("GET", "/api/status", "guest-token")["capabilities"][kFleet];
    if (fleet.contains("status") && fleet["status"].value("tasks_held", -1) == 0) return true;
    return std::nullopt;
  }));
}

TEST_CASE("fleet plugin: a reloaded fleet plugin still prices bids with the vendor's cost function") {
  TempDir dir;
  const auto token = dir.write("r2r.token", "owner-token\n");
  auto config = r2r_robot_config("alpha", token);
  config["rcan_protocol"]["capabilities"].push_back("org.rcand.test.pricing");
  config["runtime"]["plugins"] = {{"allow_reload", true}};
  RcandProcess robot(config, {plugin_dir(), test_plugin_dir() / "pricing"});
  int status = 0;
  robot.json("POST", std::string("/api/plugins/") + kFleet + "/reload", "owner-token", {}, &status);
  REQUIRE(status == 200);
  robot.json("POST", "/api/estop/clear", "owner-token", "", &status);  // a reload latches the e-stop
  REQUIRE(status == 200);
  WsClient peer;
  REQUIRE(peer.connect(robot.port(), "user-token") == 101);
  const auto bid = bid_on(peer, "req-2", "P2");
  REQUIRE(bid);
  CHECK((*bid)["payload"]["cost"] == 12.5);  // the default would be the trip time to (9, 9)
}
