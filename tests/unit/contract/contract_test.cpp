// One contract, two hosts: the same table of requests runs against the SDK's fake host (with the teleop plugin
// compiled in) and against a real rcand on loopback (the same plugin, loaded from the build tree), and both must
// answer each one with the same status, error code and field. A vendor test that passes on the fake host then
// holds on the robot (sdk/include/rcand/sdk/contract/requests.hpp has the rules both hosts call).
#include <doctest/doctest.h>

#include <rcand/sdk/testing/fake_host.hpp>
#include <rcand/sdk/testing/recording_drive.hpp>

#include <fstream>
#include <functional>
#include <string>
#include <vector>

#include "rcand_process.hpp"

extern "C" const rcand_plugin_descriptor* RCAND_ENTRY_FUNCTION(void);

using nlohmann::json;
using rcand::sdk::Role;

namespace {

struct Case {
  std::string name, method, path;
  json body;
  Role role = Role::Owner;
  bool latched = false;  // the e-stop is latched before the request (and cleared after)
  int status;
  std::string code;   // empty: no error body expected
  std::string field;  // empty: none expected
};

// The robot both hosts serve: teleop over a differential drive, nothing else.
const std::vector<Case>& cases() {
  static const json move{{"type", "move"}, {"linear", 0.1}, {"angular", 0.0}, {"duration_ms", 50}};
  static const std::vector<Case> table{
      {"an action body without a type", "POST", "/api/action", json::object(), Role::Owner, false, 400, "BAD_REQUEST", "type"},
      {"an unknown action type", "POST", "/api/action", {{"type", "fly"}}, Role::Owner, false, 400, "BAD_REQUEST", "type"},
      {"an action of an undeclared standard capability",
       "POST",
       "/api/action",
       {{"type", "grip"}},
       Role::Owner,
       false,
       404,
       "CAPABILITY_NOT_FOUND",
       ""},
      {"an undeclared custom capability", "GET", "/api/cap/com.example.none/state", json(), Role::Owner, false, 404,
       "CAPABILITY_NOT_FOUND", ""},
      {"an undeclared standard capability's endpoint", "POST", "/api/nav/waypoint", json::object(), Role::Owner, false, 404,
       "CAPABILITY_NOT_FOUND", ""},
      {"a move from a guest", "POST", "/api/action", move, Role::Guest, false, 403, "INSUFFICIENT_PRIVILEGES", ""},
      {"a move from a user", "POST", "/api/action", move, Role::User, false, 200, "", ""},
      {"a move while latched", "POST", "/api/action", move, Role::Owner, true, 423, "ESTOP_ACTIVE", ""},
      {"an invalid move",
       "POST",
       "/api/action",
       {{"type", "move"}, {"linear", "fast"}, {"angular", 0}},
       Role::Owner,
       false,
       400,
       "BAD_REQUEST",
       "linear"},
  };
  return table;
}

struct Answer {
  int status;
  json body;
};

void check(const Case& c, const Answer& answer, const char* host) {
  INFO(host << ": " << c.name << " (" << c.method << " " << c.path << ") answered " << answer.body.dump());
  CHECK(answer.status == c.status);
  if (c.status >= 300) {  // the docs/protocol.md §4 error body
    CHECK(answer.body.value("status", 0) == c.status);
    CHECK(answer.body.value("error", "") != "");
    CHECK(answer.body.value("code", "") == c.code);
    if (!c.field.empty()) CHECK(answer.body.value("field", "") == c.field);
  }
}

json teleop_manifest() {
  std::ifstream in(RCAND_SOURCE_DIR "/manifests/teleop.json");
  REQUIRE(in.good());
  return json::parse(in);
}

std::string token_of(Role role) {
  return role == Role::Guest ? "guest-token" : role == Role::User ? "user-token" : "owner-token";
}

}  // namespace

TEST_CASE("contract: the fake host answers the request table as the contract says") {
  rcand::sdk::testing::FakeHost host;
  host.add_driver_instance<rcand::sdk::testing::RecordingDrive>("drive0", host.clock());
  host.load(RCAND_ENTRY_FUNCTION, teleop_manifest());
  host.add_capability("teleop");
  for (const auto& c : cases()) {
    if (c.latched) host.latch_estop("contract test");
    const auto response = host.call(c.method, c.path, c.body, c.role);
    if (c.latched) host.clear_estop();
    check(c, {response.status, response.body}, "fake host");
  }
}

TEST_CASE("contract: a real rcand answers the same request table the same way") {
  json config = rcand::test::sim_config();
  config["drivers"] = json::array({{{"id", "drive0"}, {"protocol", "sim_diff_drive"}}});
  config["rcan_protocol"]["capabilities"] = {"status", "teleop"};
  rcand::test::RcandProcess robot(config);
  for (const auto& c : cases()) {
    if (c.latched) REQUIRE(robot.request("POST", "/api/stop", "owner-token").status == 200);
    int status = 0;
    const json body = robot.json(c.method, c.path, token_of(c.role), c.body.is_null() ? "" : c.body.dump(), &status);
    if (c.latched) REQUIRE(robot.request("POST", "/api/estop/clear", "owner-token").status == 200);
    check(c, {status, body}, "rcand");
  }
}
