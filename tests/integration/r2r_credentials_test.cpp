// Issue 13 #7: the scopes a credential grants are the claim intersected with the role's, over every transport: a
// GUEST JWT that claims "control" is refused over HTTP and over /ws/r2r alike, and the robot does not move.
#include <doctest/doctest.h>

#include <chrono>
#include <string>

#include "libs/rcan/jwt.hpp"
#include "r2r_lab.hpp"
#include "rcand_process.hpp"
#include "temp_dir.hpp"
#include "ws_client.hpp"

using namespace rcand::test;
using nlohmann::json;
using namespace std::chrono_literals;

namespace {

std::string guest_jwt_claiming_control() {
  rcand::JwtClaims claims;
  claims.sub = "sneaky-guest";
  claims.iss = "integration-test";
  claims.role = "guest";
  claims.aud = {"rcan://*"};
  claims.scope = {"status", "control"};
  claims.iat = std::chrono::duration_cast<std::chrono::seconds>(std::chrono::system_clock::now().time_since_epoch()).count();
  claims.exp = claims.iat + 600;
  return rcand::issue_jwt_hs256(claims, kJwtSecret);
}

}  // namespace

TEST_CASE("r2r credentials: a GUEST JWT claiming control cannot drive over /ws/r2r (nor over HTTP)") {
  TempDir dir;
  RcandProcess robot(r2r_robot_config("alpha", dir.write("r2r.token", "owner-token\n")));
  const std::string jwt = guest_jwt_claiming_control();
  CHECK(robot.request("POST", "/api/action", jwt, R"({"type":"move","linear":0.2,"angular":0})").status == 403);

  WsClient guest;
  REQUIRE(guest.connect(robot.port(), jwt) == 101);  // status is the guest's: it may watch the fleet
  const auto timeline_before = drive_status(robot)["timeline"].size();
  guest.send(r2r_message("sneaky-guest", "command", {{"type", "move"}, {"linear", 0.2}, {"angular", 0.0}, {"duration_ms", 100}},
                         std::string("alpha")));
  const auto refused = read_until(guest, [](const json& m) { return m.value("type", "") == "error"; });
  REQUIRE(refused);
  CHECK(refused->at("payload").value("code", 0) == 103);
  CHECK(refused->at("payload").value("message", "").find("lacks scope 'control'") != std::string::npos);
  const auto motors = drive_status(robot);
  CHECK(motors["moving"] == false);
  CHECK(motors["timeline"].size() == timeline_before);  // no motor command reached the drive
  const auto audit = robot.json("GET", "/api/audit?limit=100", "owner-token");
  for (const auto& entry : audit["entries"]) CHECK(entry.value("event", "") != "POST /api/action move");
}

TEST_CASE("r2r credentials: a GUEST watching over /ws/r2r never receives this robot's R2R token, not even in an error") {
  TempDir dir;
  RcandProcess robot(r2r_robot_config("alpha", dir.write("r2r.token", "owner-token\n")));
  WsClient guest;
  REQUIRE(guest.connect(robot.port(), "guest-token") == 101);
  guest.send(R"({"header":{"version":"1.0","timestamp":1,"source_id":"watcher"},"type":"status","payload":{"battery":"x"}})");
  int statuses = 0, errors = 0;
  const auto deadline = std::chrono::steady_clock::now() + 8s;
  while ((statuses < 2 || errors < 1) && std::chrono::steady_clock::now() < deadline) {
    const auto frame = guest.read(1000ms);
    if (!frame) continue;
    CHECK(frame->find("owner-token") == std::string::npos);
    const json message = json::parse(*frame, nullptr, false);
    CHECK_FALSE(message["header"].contains("auth"));
    statuses += message.value("type", "") == "status" ? 1 : 0;
    errors += message.value("type", "") == "error" ? 1 : 0;
  }
  CHECK(statuses >= 2);  // the broadcasts a watcher gets
  CHECK(errors >= 1);    // and the answer to its own bad message
}
