// The reference runtime's own client library (tests/interop/opencastor/client.py, vendored unmodified) against a
// running rcand: health, status, action, command, stop and clear work as its users expect, `action` in a command's
// answer is the action object that library's users read, and a call rcand does not serve fails with the error body
// (issue 30 item 5).
#include <doctest/doctest.h>

#include "rcand_process.hpp"

using namespace rcand::test;
using nlohmann::json;

TEST_CASE("the reference runtime's client library drives rcand: health, status, action, command, stop, clear") {
  auto config = sim_config();
  config["rcan_protocol"]["capabilities"] = {"status", "teleop", "nav", "chat"};
  config["agent"] = {{"provider", "grammar"}};
  RcandProcess rcand(config);
  const std::string script = std::string(RCAND_SOURCE_DIR) + "/tests/interop/opencastor/drive_reference_client.py";
  const auto run = run_tool("/usr/bin/python3", {script, "http://127.0.0.1:" + std::to_string(rcand.port()), "owner-token"});
  INFO(run.out, run.err);
  REQUIRE(run.exit_code == 0);
  const json r = json::parse(run.out);

  CHECK(r["health"]["ok"] == true);
  CHECK(r["status"]["ok"] == true);
  CHECK(r["status"]["answer"].contains("capabilities"));
  CHECK(r["action"]["ok"] == true);

  const json& command = r["command"];
  REQUIRE(command["ok"] == true);
  CHECK(command["answer"]["action"]["type"] == "nav_waypoint");  // what the library's users read
  CHECK(command["answer"]["action"]["heading_deg"] == 90.0);
  CHECK(command["answer"]["request"]["path"] == "/api/nav/waypoint");  // what rcand dispatched
  CHECK(command["answer"]["dispatched"] == true);

  CHECK(r["stop"]["ok"] == true);
  CHECK(r["stop"]["answer"]["motors_stopped"] == true);
  CHECK(r["action_while_stopped"]["ok"] == false);  // latched: the library raises CastorError with rcand's error
  CHECK(r["action_while_stopped"]["status"] == 423);
  CHECK(r["action_while_stopped"]["body"]["code"] == "ESTOP_ACTIVE");
  CHECK(r["estop_clear"]["ok"] == true);
  CHECK(r["action_after_clear"]["ok"] == true);

  // Not an rcand route: the library surfaces rcand's error body, message included.
  CHECK(r["memory_episodes"]["ok"] == false);
  CHECK(r["memory_episodes"]["status"] == 404);
  CHECK(r["memory_episodes"]["body"].contains("code"));
  CHECK(r["memory_episodes"]["message"].get<std::string>().rfind("HTTP 404: ", 0) == 0);
}
