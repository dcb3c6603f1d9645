// R2R over WebSocket against a real rcand: a test client plays a foreign robot on WS /ws/r2r and gets every error
// code from its defining condition (100 malformed and unknown type, 101 unknown target, 102 second claim, 103 not
// allowed, 104 silent winner, 105 command while e-stopped - with no motion), sees commands move the sim drive,
// bids and awards round-trip, and a frame over 64 KiB closes with 1009.
#include <doctest/doctest.h>

#include <chrono>
#include <functional>

#include "r2r_lab.hpp"
#include "rcand_process.hpp"
#include "ws_client.hpp"

using namespace rcand::test;
using nlohmann::json;
using namespace std::chrono_literals;

namespace {

const json kR2rMove = {{"type", "move"}, {"linear", 0.3}, {"angular", 0.0}, {"duration_ms", 3000}};


}  // namespace

TEST_CASE("r2r ws: malformed, unknown type and unknown target are answered on the same connection (100, 101)") {
  TempDir dir;
  const auto token = dir.write("r2r.token", "owner-token\n");
  RcandProcess robot(r2r_robot_config("alpha", token));
  WsClient peer;
  REQUIRE(peer.connect(robot.port(), "user-token") == 101);

  peer.send("this is not json");
  auto answer = read_until(peer, error_with(100));
  REQUIRE(answer);
  CHECK((*answer)["header"]["source_id"] == "alpha");

  peer.send(r2r_message("probe", "teleport", json::object()));
  answer = read_until(peer, error_with(100));
  REQUIRE(answer);
  CHECK((*answer)["header"]["target_id"] == "probe");  // answered to its sender, by name
  CHECK((*answer)["payload"]["ref"]["source_id"] == "probe");

  peer.send(r2r_message("probe", "status", {{"battery", 50}}, std::string("nobody")));
  answer = read_until(peer, error_with(101));
  REQUIRE(answer);

  // The robot is still fine, and counted what it refused.
  const auto peers = robot.json("GET", "/api/r2r/peers", "guest-token");
  CHECK(peers["counters"]["rejected"].get<int>() >= 3);
  CHECK(robot.json("GET", "/health")["status"] == "ok");
}

TEST_CASE("r2r ws: an upgrade without credentials is 401; a guest's command is 103; a frame over 64 KiB closes with 1009") {
  TempDir dir;
  const auto token = dir.write("r2r.token", "owner-token\n");
  RcandProcess robot(r2r_robot_config("alpha", token));
  WsClient anonymous;
  CHECK(anonymous.connect(robot.port(), "") == 401);

  WsClient guest;
  REQUIRE(guest.connect(robot.port(), "guest-token") == 101);
  guest.send(r2r_message("guest-bot", "command", kR2rMove, std::string("alpha")));
  REQUIRE(read_until(guest, error_with(103)));
  CHECK(drive_status(robot)["moving"] == false);

  WsClient big;
  REQUIRE(big.connect(robot.port(), "user-token") == 101);
  big.send(r2r_message("big-bot", "status", {{"pad", std::string(70 * 1024, 'x')}}));
  boost::beast::error_code error;
  for (int frames = 0; frames < 10 && big.read(5s, &error); ++frames) {
  }  // a status broadcast may come first; then the close (answering it may meet the socket already gone: EPIPE)
  CHECK(error);
  CHECK(big.ws.reason().code == boost::beast::websocket::close_code::too_big);
  CHECK(robot.json("GET", "/health")["status"] == "ok");
}

TEST_CASE("r2r ws: a command moves the sim drive; while e-stopped it is answered 105 and nothing moves") {
  TempDir dir;
  const auto token = dir.write("r2r.token", "owner-token\n");
  RcandProcess robot(r2r_robot_config("alpha", token));
  WsClient peer;
  REQUIRE(peer.connect(robot.port(), "user-token") == 101);

  peer.send(r2r_message("commander", "command", kR2rMove, std::string("alpha")));
  CHECK(poll_until<bool>([&]() -> std::optional<bool> {
    if (drive_status(robot)["moving"] == true) return true;
    return std::nullopt;
  }));
  // The command went through the same path as POST /api/action: audited as the WebSocket's principal.
  bool audited = false;
  const auto audit = robot.json("GET", "/api/audit?limit=50", "owner-token");
  for (const auto& entry : audit["entries"])
    if (entry["event"] == "POST /api/action move" && entry["principal"].get<std::string>().find("user-principal") != std::string::npos)
      audited = true;
  INFO("audit: " << audit.dump());
  CHECK(audited);

  int status = 0;
  robot.json("POST", "/api/stop", "guest-token", "", &status);
  REQUIRE(status == 200);
  const auto timeline_before = drive_status(robot)["timeline"].size();
  peer.send(r2r_message("commander", "command", kR2rMove, std::string("alpha")));
  const auto refused = read_until(peer, error_with(105));
  REQUIRE(refused);
  CHECK((*refused)["payload"]["http_status"] == 423);
  const auto motors = drive_status(robot);
  CHECK(motors["moving"] == false);
  CHECK(motors["timeline"].size() == timeline_before);  // no motor command at all
  CHECK(robot.json("GET", "/api/status", "guest-token")["estopped"] == true);
}

TEST_CASE("r2r ws: bid, award and task_response round-trip; a second claim from another requester is 102") {
  TempDir dir;
  const auto token = dir.write("r2r.token", "owner-token\n");
  RcandProcess robot(r2r_robot_config("alpha", token, 3.0, 4.0));
  WsClient peer;
  REQUIRE(peer.connect(robot.port(), "user-token") == 101);

  peer.send(r2r_message("req-1", "task_request",
                        {{"task_id", "T1"}, {"description", "fetch"}, {"required_capabilities", {"teleop"}},
                         {"location", {{"x", 0.0}, {"y", 0.0}}}, {"bid_deadline", unix_now() + 10}}));
  const auto bid = read_until(peer, [](const json& m) { return m.value("type", "") == "negotiation"; });
  REQUIRE(bid);
  CHECK((*bid)["payload"]["action"] == "bid");
  CHECK((*bid)["payload"]["task_id"] == "T1");
  CHECK((*bid)["payload"]["cost"].get<double>() > 0);  // 5 m away from the task
  CHECK((*bid)["header"]["target_id"] == "req-1");

  peer.send(r2r_message("req-1", "negotiation", {{"task_id", "T1"}, {"action", "award"}}, std::string("alpha")));
  const auto accepted = read_until(peer, [](const json& m) { return m.value("type", "") == "task_response"; });
  REQUIRE(accepted);
  CHECK((*accepted)["payload"]["accepted"] == true);
  CHECK((*accepted)["payload"]["estimated_time"].is_number());

  peer.send(r2r_message("req-2", "negotiation", {{"task_id", "T1"}, {"action", "award"}}, std::string("alpha")));
  REQUIRE(read_until(peer, error_with(102)));
  const auto held = robot.json("GET", "/api/r2r/peers", "guest-token")["held_tasks"];
  REQUIRE(held.size() == 1);
  CHECK(held[0]["requester"] == "req-1");
}

TEST_CASE("r2r ws: a winner that goes silent gets 104 and the auction re-opens without it") {
  TempDir dir;
  const auto token = dir.write("r2r.token", "owner-token\n");
  RcandProcess robot(r2r_robot_config("alpha", token));
  WsClient ghost;
  REQUIRE(ghost.connect(robot.port(), "user-token") == 101);
  ghost.send(r2r_message("ghost", "status", {{"battery", 90}}));  // announces itself: now addressable as "ghost"
  REQUIRE(poll_until<json>([&] { return peer_status(robot, "ghost"); }));

  int status = 0;
  const auto opened = robot.json("POST", "/api/r2r/auction", "user-token",
                                 json{{"required_capabilities", json::array()}, {"wait", false}}.dump(), &status);
  REQUIRE(status == 202);
  const std::string task_id = opened["task_id"];
  const auto request = read_until(ghost, [&](const json& m) {
    return m.value("type", "") == "task_request" && m["payload"].value("task_id", "") == task_id;
  });
  REQUIRE(request);
  ghost.send(r2r_message("ghost", "negotiation", {{"task_id", task_id}, {"action", "bid"}, {"cost", 1.0}, {"capabilities", json::array()}},
                         std::string("alpha")));
  const auto award = read_until(ghost, [](const json& m) {
    return m.value("type", "") == "negotiation" && m["payload"].value("action", "") == "award";
  });
  REQUIRE(award);
  // ... and the ghost never answers.
  const auto timeout = read_until(ghost, error_with(104), 10s);
  REQUIRE(timeout);
  const auto result = robot.json("GET", "/api/r2r/auction/" + task_id, "guest-token");
  CHECK(result["round"].get<int>() >= 2);
  CHECK(result["excluded"] == json::array({"ghost"}));
}
