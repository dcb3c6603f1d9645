// Plugin loading failure modes (design.md "The plugin boundary") against a running rcand: each fixture ends in its
// exact recorded state, and every other plugin keeps serving.
#include <doctest/doctest.h>

#include <fstream>
#include <map>

#include "eventually.hpp"
#include "rcand_process.hpp"

using namespace rcand::test;
using nlohmann::json;

namespace {

const std::vector<std::string> kFixtureCapabilities{
    "org.rcand.test.good",          "org.rcand.test.throws_in_handler", "org.rcand.test.abi_major",
    "org.rcand.test.newer_minor",   "org.rcand.test.no_entry",          "org.rcand.test.mismatch",
    "org.rcand.test.throws_in_register", "org.rcand.test.undefined_symbol", "org.rcand.test.version_mismatch"};

// Plugin records by manifest file name (the duplicate shares its id with `good`).
std::map<std::string, json> records_by_manifest(const RcandProcess& rcand) {
  std::map<std::string, json> records;
  const json document = rcand.json("GET", "/api/plugins", "owner-token");  // manifest paths are for config callers
  for (const auto& record : document["plugins"])
    records[std::filesystem::path(record["manifest"].get<std::string>()).filename().string()] = record;
  return records;
}

}  // namespace

TEST_CASE("each broken plugin ends in its exact state and the others still serve") {
  auto config = sim_config();
  json caps = {"status", "teleop", "com.acme.gripper"};
  for (const auto& name : kFixtureCapabilities) caps.push_back(name);
  config["rcan_protocol"]["capabilities"] = caps;
  RcandProcess rcand(config, {plugin_dir(), test_plugin_dir()});
  auto records = records_by_manifest(rcand);

  const std::vector<std::pair<std::string, std::string>> expected{
      {"good.json", "loaded"},
      {"throws_in_handler.json", "loaded"},
      {"abi_major.json", "incompatible-abi"},
      {"newer_minor.json", "incompatible-abi"},
      {"no_entry.json", "failed-to-open"},
      {"undefined_symbol.json", "failed-to-open"},
      {"mismatch.json", "manifest-mismatch"},
      {"version_mismatch.json", "manifest-mismatch"},
      {"throws_in_register.json", "registration-failed"},
      {"good_duplicate.json", "duplicate-id"},
      {"bad_manifest.json", "invalid-manifest"},
      {"teleop.json", "loaded"},
      {"sim_drive.json", "loaded"},
      {"com.acme.gripper.json", "loaded"},
  };
  for (const auto& entry : expected) {
    // Named references, not structured bindings: CAPTURE makes a lambda, and clang 14 cannot capture a binding.
    const auto& manifest = std::get<0>(entry); const auto& state = std::get<1>(entry);
    CAPTURE(manifest);
    REQUIRE(records.count(manifest) == 1);
    CHECK(records[manifest]["state"] == state);
    if (state != "loaded") {
      CHECK_FALSE(records[manifest]["reason"].get<std::string>().empty());
      CHECK_FALSE(records[manifest]["hint"].get<std::string>().empty());
    }
  }
  CHECK(records["abi_major.json"]["reason"].get<std::string>().find("ABI 2") != std::string::npos);
  CHECK(records["undefined_symbol.json"]["reason"].get<std::string>().find("undefined symbol") != std::string::npos);

  int status = 0;
  // A capability whose plugin failed to load is declared (config is authoritative, §9.5) but out of service.
  auto unavailable = rcand.json("GET", "/api/cap/org.rcand.test.abi_major/ping", "user-token", "", &status);
  CHECK(status == 503);
  CHECK(unavailable["code"] == "UNAVAILABLE");

  // The good plugin serves; a throwing handler fails its request with 500, every time, and its capability stays in
  // service (docs/protocol.md §7.16): the throws are counted, the message stays in the log...
  CHECK(rcand.json("GET", "/api/cap/org.rcand.test.good/ping", "user-token", "", &status)["ok"] == true);
  CHECK(status == 200);
  for (int i = 0; i < 2; ++i) {
    auto boom = rcand.json("GET", "/api/cap/org.rcand.test.throws_in_handler/boom", "user-token", "", &status);
    CHECK(status == 500);
    CHECK(boom["code"] == "INTERNAL");
    CHECK(boom["error"].get<std::string>().find("exploded") == std::string::npos);  // internals stay in the log
  }
  CHECK(eventually([&] {
    const auto robot = rcand.json("GET", "/api/status", "guest-token");
    return robot["capabilities"]["org.rcand.test.throws_in_handler"].value("handler_errors", 0) == 2;
  }));
  auto robot = rcand.json("GET", "/api/status", "guest-token");
  CHECK(robot["capabilities"]["org.rcand.test.throws_in_handler"]["state"] == "ok");
  CHECK(rcand.stderr_text().find("handler exploded on purpose") != std::string::npos);

  // ...and everything else keeps serving, motion included, and the e-stop still works.
  CHECK(rcand.json("GET", "/api/cap/org.rcand.test.good/ping", "user-token", "", &status)["ok"] == true);
  rcand.json("POST", "/api/action", "user-token", R"({"type":"move","linear":0.3,"angular":0,"duration_ms":1000})", &status);
  CHECK(status == 200);
  CHECK(rcand.json("GET", "/api/drivers/drive0", "guest-token")["status"]["moving"] == true);
  rcand.json("POST", "/api/stop", "user-token", "", &status);
  CHECK(status == 200);
  CHECK(rcand.json("GET", "/api/drivers/drive0", "guest-token")["status"]["moving"] == false);
  CHECK(rcand.stop() == 0);
}

TEST_CASE("rcand --check-plugins prints the table and exits non-zero on failures") {
  auto broken = run_tool(rcand_binary(), {"--check-plugins", "--plugin-path", plugin_dir().string(), "--plugin-path",
                                          test_plugin_dir().string()});
  CHECK(broken.exit_code == 1);
  for (auto text : {"org.rcand.test.abi_major", "incompatible-abi", "failed-to-open", "manifest-mismatch", "registration-failed",
                    "duplicate-id", "invalid-manifest", "org.rcand.teleop", "loaded"})
    CHECK(broken.out.find(text) != std::string::npos);

  auto clean = run_tool(rcand_binary(), {"--check-plugins", "--plugin-path", plugin_dir().string()});
  CHECK(clean.exit_code == 0);
  CHECK(clean.out.find("com.acme.gripper") != std::string::npos);
  CHECK(clean.out.find("failed") == std::string::npos);
}

TEST_CASE("plugins that the config does not need are not opened") {
  auto config = sim_config();
  config["rcan_protocol"]["capabilities"] = {"status", "teleop"};
  config["drivers"] = json::array({{{"id", "drive0"}, {"protocol", "sim_diff_drive"}}});
  RcandProcess rcand(config, {plugin_dir(), test_plugin_dir()});
  auto records = records_by_manifest(rcand);
  CHECK(records["com.acme.gripper.json"]["state"] == "installed-not-enabled");
  CHECK(records["abi_major.json"]["state"] == "installed-not-enabled");
  CHECK(records["teleop.json"]["state"] == "loaded");
  // The library was never mapped into the process.
  std::ifstream maps("/proc/" + std::to_string(rcand.pid()) + "/maps");
  std::string text((std::istreambuf_iterator<char>(maps)), std::istreambuf_iterator<char>());
  CHECK(text.find("rcand_teleop") != std::string::npos);
  CHECK(text.find("acme_gripper") == std::string::npos);
  CHECK(text.find("abi_major") == std::string::npos);
}
