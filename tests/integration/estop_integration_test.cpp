// docs/protocol.md §6 against a running rcand on the sim drive: the latched e-stop, the motion gate on every motion path,
// the dead-man watchdog and the audit log, read back from the sim drive's motor timeline.
#include <doctest/doctest.h>

#include <chrono>

#include "rcand_process.hpp"

using namespace rcand::test;
using nlohmann::json;

namespace {

int count_commands(const RcandProcess& rcand) { return drive_status(rcand)["commands"].get<int>(); }

// Polls the drive until both wheels are at zero (the watchdog is asynchronous); bounded so a failure cannot hang.
json wait_for_zero(const RcandProcess& rcand, std::chrono::seconds limit) {
  const auto deadline = std::chrono::steady_clock::now() + limit;
  json status;
  do {
    status = drive_status(rcand);
    if (!status["moving"].get<bool>()) return status;
  } while (std::chrono::steady_clock::now() < deadline);
  return status;
}

const std::string kMove = R"({"type":"move","linear":0.5,"angular":0.1,"duration_ms":5000})";

}  // namespace

TEST_CASE("e-stop: POST /api/stop latches, halts the drive, answers after the halt, and blocks every motion path") {
  RcandProcess rcand(sim_config());
  int status = 0;
  auto moved = rcand.json("POST", "/api/action", "user-token", kMove, &status);
  REQUIRE(status == 200);
  CHECK(moved["ok"] == true);
  CHECK(drive_status(rcand)["moving"] == true);

  const auto before = std::chrono::steady_clock::now();
  auto stopped = rcand.json("POST", "/api/stop", "guest-token", "", &status);  // any valid token (scope status)
  const auto elapsed = std::chrono::steady_clock::now() - before;
  REQUIRE(status == 200);
  CHECK(elapsed < std::chrono::milliseconds(500));  // the §15.5 MUST, with the whole HTTP round trip included
  CHECK(stopped["status"] == "stopped");
  CHECK(stopped["estopped"] == true);
  CHECK(stopped["motors_stopped"] == true);
  CHECK(stopped["latency_us"].is_number());
  REQUIRE(stopped["drivers"].size() == 2);  // drive0 and gripper0 both actuate
  for (const auto& driver : stopped["drivers"]) CHECK(driver["halted"] == true);

  // The motors were at zero when the answer was sent: the halt event precedes "now" and nothing moved after it.
  auto drive = drive_status(rcand);
  CHECK(drive["moving"] == false);
  CHECK(drive["left"] == 0.0);
  CHECK(drive["right"] == 0.0);
  CHECK(drive["timeline"].back()["cause"] == "halt");

  auto estop = rcand.json("GET", "/api/estop", "guest-token");
  CHECK(estop["estopped"] == true);
  CHECK(estop["since_ms"].is_number());
  CHECK(estop["source"] == "guest-principal");
  CHECK(estop["reason"].is_string());

  // Every motion path that exists refuses with 423 and the drivers receive nothing.
  const int commands = count_commands(rcand);
  auto refused = rcand.json("POST", "/api/action", "owner-token", kMove, &status);
  CHECK(status == 423);
  CHECK(refused["code"] == "ESTOP_ACTIVE");
  CHECK(refused["status"] == 423);
  rcand.json("POST", "/api/action", "owner-token", R"({"type":"move","linear":0.2,"angular":0})", &status);
  CHECK(status == 423);
  rcand.json("POST", "/api/cap/com.acme.gripper/grip", "owner-token", R"({"state":"close"})", &status);
  CHECK(status == 423);
  CHECK(count_commands(rcand) == commands);
  CHECK(rcand.json("GET", "/api/cap/com.acme.gripper/state", "owner-token")["opening"].is_number());

  // A non-motion stop is still allowed, and /api/status reports the state.
  rcand.json("POST", "/api/action", "user-token", R"({"type":"stop"})", &status);
  CHECK(status == 200);
  auto robot = rcand.json("GET", "/api/status", "guest-token");
  CHECK(robot["estopped"] == true);
  CHECK(robot["state"] == "estop");
  CHECK(rcand.json("GET", "/api/discovery")["status"] == "estop");

  // Clearing needs config scope; after it, motion works again.
  rcand.json("POST", "/api/estop/clear", "user-token", "", &status);
  CHECK(status == 403);
  auto cleared = rcand.json("POST", "/api/estop/clear", "owner-token", "", &status);
  CHECK(status == 200);
  CHECK(cleared["status"] == "cleared");
  CHECK(rcand.json("GET", "/api/estop", "guest-token")["estopped"] == false);
  rcand.json("POST", "/api/action", "user-token", kMove, &status);
  CHECK(status == 200);
  CHECK(count_commands(rcand) == commands + 1);
}

TEST_CASE("e-stop: a malformed body never prevents a stop") {
  RcandProcess rcand(sim_config());
  int status = 0;
  rcand.json("POST", "/api/stop", "user-token", "{not json", &status);
  CHECK(status == 200);
  CHECK(rcand.json("GET", "/api/estop", "user-token")["estopped"] == true);
}

TEST_CASE("e-stop: safety.estop_on_startup starts the robot latched") {
  auto config = sim_config();
  config["safety"]["estop_on_startup"] = true;
  RcandProcess rcand(config);
  int status = 0;
  auto estop = rcand.json("GET", "/api/estop", "owner-token");
  CHECK(estop["estopped"] == true);
  CHECK(estop["source"] == "config");
  rcand.json("POST", "/api/action", "owner-token", kMove, &status);
  CHECK(status == 423);
  CHECK(count_commands(rcand) == 0);
}

TEST_CASE("teleop: a move without duration_ms is a dead-man command stopped by the watchdog") {
  auto config = sim_config();
  config["safety"]["watchdog_ms"] = 300;
  RcandProcess rcand(config);
  int status = 0;
  rcand.json("POST", "/api/action", "user-token", R"({"type":"move","linear":0.4,"angular":0})", &status);
  REQUIRE(status == 200);
  const auto drive = wait_for_zero(rcand, std::chrono::seconds(5));
  REQUIRE(drive["moving"] == false);
  // From the timeline: the move, then a stop ~watchdog_ms later (not an e-stop).
  const auto& timeline = drive["timeline"];
  REQUIRE(timeline.size() >= 2);
  const auto& move = timeline[timeline.size() - 2];
  const auto& stop = timeline.back();
  CHECK(move["left"] == doctest::Approx(0.4));
  CHECK(stop["left"] == 0.0);
  const double held_ms = (stop["t_us"].get<double>() - move["t_us"].get<double>()) / 1000.0;
  CHECK(held_ms >= 300.0);
  CHECK(held_ms < 300.0 + 250.0);  // generous: the worker wakes on a timer, this is not a benchmark
  CHECK(rcand.json("GET", "/api/estop", "user-token")["estopped"] == false);
}

TEST_CASE("audit: commands are recorded with principal and outcome, newest first; GET needs config scope") {
  RcandProcess rcand(sim_config());
  int status = 0;
  rcand.json("POST", "/api/action", "user-token", kMove, &status);
  rcand.json("POST", "/api/stop", "user-token", "", &status);
  rcand.json("POST", "/api/action", "user-token", kMove, &status);  // blocked
  rcand.request("POST", "/api/action", "user-token", kMove, {{"X-Message-Id", "client-42"}});
  auto audit = rcand.json("GET", "/api/audit", "owner-token", "", &status);
  REQUIRE(status == 200);
  const auto& entries = audit["entries"];
  REQUIRE(entries.size() >= 4);
  CHECK(entries[0]["message_id"] == "client-42");
  CHECK(entries[0]["outcome"] == "blocked");
  CHECK(entries[1]["outcome"] == "blocked");
  CHECK(entries[2]["event"] == "POST /api/stop");
  CHECK(entries[2]["outcome"] == "ok");
  CHECK(entries[3]["outcome"] == "ok");
  CHECK(entries[3]["event"] == "POST /api/action move");
  for (const auto& entry : entries) {
    CHECK(entry["principal"] == "user-principal");
    CHECK(entry["ruri"] == "rcan://rcand.sim-rover.1a2b3c4d");
    for (auto key : {"timestamp_ms", "message_id", "event", "outcome"}) CHECK(entry.contains(key));
  }
}
