// Navigation (seed §10, docs/protocol.md §8) against a running rcand on the sim drive, read back from the drive's motor
// timeline (t_us on the kernel's steady clock): turn-then-drive durations, one job at a time, validation that never
// moves a wheel, cancel and e-stop mid-turn and mid-drive, a throwing driver, and the obstacle stop (§10.5).
#include <doctest/doctest.h>

#include <chrono>
#include <cmath>
#include <numbers>

#include "rcand_process.hpp"

using namespace rcand::test;
using nlohmann::json;

namespace {

json nav_config() {
  auto config = sim_config();
  config["rcan_protocol"]["capabilities"] = {"status", "teleop", "nav", "com.acme.gripper"};
  return config;
}

json nav_status(const RcandProcess& rcand) { return rcand.json("GET", "/api/nav/status", "guest-token"); }

// Polls until `done(status)` or the deadline; returns the last status. Bounded so a failure cannot hang.
template <class Pred> json poll_nav(const RcandProcess& rcand, Pred done, std::chrono::milliseconds limit = std::chrono::seconds(10)) {
  const auto deadline = std::chrono::steady_clock::now() + limit;
  json status;
  do {
    status = nav_status(rcand);
    if (done(status)) return status;
  } while (std::chrono::steady_clock::now() < deadline);
  return status;
}
json wait_idle(const RcandProcess& rcand) {
  return poll_nav(rcand, [](const json& s) { return s["running"] == false; });
}

json waypoint(const RcandProcess& rcand, double distance, double heading, double speed, int* status) {
  return rcand.json("POST", "/api/nav/waypoint", "user-token",
                    json{{"distance_m", distance}, {"heading_deg", heading}, {"speed", speed}}.dump(), status);
}

// The timeline events at or after `from_us`.
std::vector<json> events_since(const json& drive, std::int64_t from_us) {
  std::vector<json> out;
  for (const auto& e : drive["timeline"])
    if (e["t_us"].get<std::int64_t>() >= from_us) out.push_back(e);
  return out;
}

// The motors went to zero within 5 ms of `request_us` and nothing moved them afterwards.
void check_zero_within_5ms(const json& drive, std::int64_t request_us) {
  const auto after = events_since(drive, request_us);
  REQUIRE_FALSE(after.empty());
  CHECK(after.front()["left"] == 0.0);
  CHECK(after.front()["right"] == 0.0);
  CHECK(after.front()["t_us"].get<std::int64_t>() - request_us < 5000);
  for (const auto& e : after) {
    CHECK(e["left"] == 0.0);
    CHECK(e["right"] == 0.0);
  }
  CHECK(drive["moving"] == false);
}

}  // namespace

TEST_CASE("nav: a waypoint turns, then drives, for the computed durations, and always stops") {
  RcandProcess rcand(nav_config());
  CHECK(rcand.json("GET", "/api/discovery")["capabilities"] == json{"status", "teleop", "nav", "com.acme.gripper"});
  int status = 0;
  // Turn 45 deg at speed 1: 45 x 0.008 = 360 ms. Drive 0.105 m at 0.21 m/s: 500 ms.
  auto answer = waypoint(rcand, 0.105, 45, 1.0, &status);
  REQUIRE(status == 200);
  CHECK(answer["ok"] == true);
  CHECK(answer["job_id"].get<std::string>().rfind("nav-", 0) == 0);
  CHECK(answer["eta_ms"] == 860);
  const auto started = answer["started_us"].get<std::int64_t>();

  auto running = nav_status(rcand);
  CHECK(running["job_id"] == answer["job_id"]);
  const auto final_status = wait_idle(rcand);
  REQUIRE(final_status["running"] == false);
  CHECK(final_status["state"] == "done");
  CHECK(final_status["result"]["ok"] == true);
  CHECK(final_status["result"]["reason"] == "completed");
  CHECK(final_status["elapsed_ms"].get<int>() >= 860);
  CHECK(final_status["distance_m"] == 0.105);
  CHECK(final_status["heading_deg"] == 45.0);
  CHECK(final_status["speed"] == 1.0);
  CHECK(final_status["eta_ms"] == 860);

  const auto drive = drive_status(rcand);
  const auto events = events_since(drive, started - 5000);
  REQUIRE(events.size() >= 3);
  CHECK(events[0]["cause"] == "command");
  CHECK(events[0]["left"] == -1.0);  // counter-clockwise: left wheel back, right forward
  CHECK(events[0]["right"] == 1.0);
  CHECK(events[1]["cause"] == "command");
  CHECK(events[1]["left"] == 1.0);
  CHECK(events[1]["right"] == 1.0);
  CHECK(events[2]["cause"] == "halt");
  const auto turn_us = events[1]["t_us"].get<std::int64_t>() - events[0]["t_us"].get<std::int64_t>();
  const auto drive_us = events[2]["t_us"].get<std::int64_t>() - events[1]["t_us"].get<std::int64_t>();
  CHECK(std::abs(turn_us - 360'000) < 20'000);
  CHECK(std::abs(drive_us - 500'000) < 20'000);
  CHECK(drive["moving"] == false);

  // The dead-reckoned pose, in nav status and top level in /api/status: 0.105 m at 45 degrees.
  const auto pose = rcand.json("GET", "/api/status", "guest-token")["pose"];
  CHECK(pose["heading_deg"].get<double>() == doctest::Approx(45.0).epsilon(0.001));
  CHECK(pose["x_m"].get<double>() == doctest::Approx(0.105 * std::cos(std::numbers::pi / 4)).epsilon(0.001));
  CHECK(pose["y_m"].get<double>() == doctest::Approx(0.105 * std::sin(std::numbers::pi / 4)).epsilon(0.001));
  CHECK(final_status["pose"] == pose);
}

TEST_CASE("nav: one job at a time (409 NAV_BUSY); each invalid input is 400 naming the field and moves nothing") {
  RcandProcess rcand(nav_config());
  int status = 0;
  const std::vector<std::pair<std::string, std::string>> bad = {
      {R"({"heading_deg":0})", "distance_m"},
      {R"({"distance_m":"far","heading_deg":0})", "distance_m"},
      {R"({"distance_m":1})", "heading_deg"},
      {R"({"distance_m":1,"heading_deg":null})", "heading_deg"},
      {R"({"distance_m":1,"heading_deg":0,"speed":0})", "speed"},
      {R"({"distance_m":1,"heading_deg":0,"speed":1.5})", "speed"},
      {R"({"distance_m":1,"heading_deg":0,"speed":-0.2})", "speed"},
      {R"({"distance_m":1,"heading_deg":0,"speed":"max"})", "speed"},
      {R"([1,2])", "body"},
      {R"(not json)", "body"},
  };
  for (const auto& entry : bad) {
    // Named references, not structured bindings: CAPTURE makes a lambda, and clang 14 cannot capture a binding.
    const auto& body = std::get<0>(entry); const auto& field = std::get<1>(entry);
    CAPTURE(body);
    auto answer = rcand.json("POST", "/api/nav/waypoint", "user-token", body, &status);
    CHECK(status == 400);
    CHECK(answer["code"] == "BAD_REQUEST");
    CHECK(answer["field"] == field);
  }
  CHECK(drive_status(rcand)["commands"] == 0);
  CHECK(nav_status(rcand)["state"] == "idle");

  auto first = waypoint(rcand, 1.0, 90, 0.5, &status);  // 1.44 s turn + 9.5 s drive
  REQUIRE(status == 200);
  auto second = waypoint(rcand, 0.5, 0, 0.5, &status);
  CHECK(status == 409);
  CHECK(second["code"] == "NAV_BUSY");
  CHECK(second["job_id"] == first["job_id"]);
  CHECK(rcand.json("GET", "/api/status", "guest-token")["nav_running"] == true);
  CHECK(rcand.json("GET", "/api/status", "guest-token")["state"] == "running");
  auto cancelled = rcand.json("POST", "/api/nav/cancel", "user-token", "", &status);
  CHECK(status == 200);
  CHECK(cancelled["cancelled"] == true);
  CHECK(nav_status(rcand)["job_id"] == first["job_id"]);
  waypoint(rcand, 0.0, 0, 0.5, &status);  // free again
  CHECK(status == 200);
}

TEST_CASE("nav: cancel mid-turn and mid-drive stops the motors within 5 ms, without latching the e-stop") {
  RcandProcess rcand(nav_config());
  for (const char* phase : {"turning", "driving"}) {
    CAPTURE(phase);
    int status = 0;
    // Turn 90 deg at 0.5: 1.44 s; drive 1 m at 0.105 m/s: 9.5 s.
    auto answer = waypoint(rcand, 1.0, 90, 0.5, &status);
    REQUIRE(status == 200);
    REQUIRE(poll_nav(rcand, [&](const json& s) { return s["state"] == phase; })["state"] == phase);
    auto cancelled = rcand.json("POST", "/api/nav/cancel", "user-token", "", &status);
    REQUIRE(status == 200);
    CHECK(cancelled["cancelled"] == true);
    CHECK(cancelled["job_id"] == answer["job_id"]);
    CHECK(cancelled["state"] == "aborted");
    CHECK(cancelled["result"]["ok"] == false);
    CHECK(cancelled["result"]["reason"] == "cancelled");
    check_zero_within_5ms(drive_status(rcand), cancelled["received_us"].get<std::int64_t>());
    CHECK(rcand.json("GET", "/api/estop", "guest-token")["estopped"] == false);
    CHECK(nav_status(rcand)["running"] == false);
  }
}

TEST_CASE("nav: an e-stop mid-turn and mid-drive halts at once, not at the end of the phase, and the job says why") {
  RcandProcess rcand(nav_config());
  for (const char* phase : {"turning", "driving"}) {
    CAPTURE(phase);
    int status = 0;
    REQUIRE(rcand.json("POST", "/api/estop/clear", "owner-token", "", &status)["status"] == "cleared");
    auto answer = waypoint(rcand, 1.0, 90, 0.5, &status);
    REQUIRE(status == 200);
    REQUIRE(poll_nav(rcand, [&](const json& s) { return s["state"] == phase; })["state"] == phase);
    auto stopped = rcand.json("POST", "/api/stop", "guest-token", "", &status);
    REQUIRE(status == 200);
    check_zero_within_5ms(drive_status(rcand), stopped["received_us"].get<std::int64_t>());
    const auto ended = wait_idle(rcand);
    CHECK(ended["job_id"] == answer["job_id"]);
    CHECK(ended["state"] == "aborted");
    CHECK(ended["result"]["ok"] == false);
    CHECK(ended["result"]["reason"] == "estop");
    CHECK(ended["elapsed_ms"].get<int>() < 5000);  // ended at the stop, not after the 11 s job

    // A job cannot start while latched: 423 and the drive receives nothing.
    const auto commands = drive_status(rcand)["commands"];
    auto refused = waypoint(rcand, 0.5, 0, 0.5, &status);
    CHECK(status == 423);
    CHECK(refused["code"] == "ESTOP_ACTIVE");
    CHECK(drive_status(rcand)["commands"] == commands);
  }
}

TEST_CASE("nav: a driver that throws mid-job still ends with the motors at zero; one that fails at once answers 503") {
  SUBCASE("the drive command throws after the turn") {
    auto config = nav_config();
    config["drivers"][0]["fail_after_commands"] = 2;
    RcandProcess rcand(config);
    int status = 0;
    waypoint(rcand, 0.2, 30, 1.0, &status);  // 240 ms turn, then the drive command throws
    REQUIRE(status == 200);
    const auto ended = wait_idle(rcand);
    CHECK(ended["state"] == "aborted");
    CHECK(ended["result"]["reason"] == "actuator_failed");
    const auto drive = drive_status(rcand);
    CHECK(drive["moving"] == false);
    CHECK(drive["timeline"].back()["cause"] == "halt");
    auto refused = waypoint(rcand, 0.2, 0, 1.0, &status);
    CHECK(status == 503);
    CHECK(refused["code"] == "UNAVAILABLE");
    CHECK(rcand.json("GET", "/api/status", "guest-token")["state"] == "error");
  }
  SUBCASE("the first command throws: the job never starts") {
    auto config = nav_config();
    config["drivers"][0]["fail_after_commands"] = 1;
    RcandProcess rcand(config);
    int status = 0;
    auto refused = waypoint(rcand, 0.2, 30, 1.0, &status);
    CHECK(status == 503);
    CHECK(refused["code"] == "UNAVAILABLE");
    CHECK(refused["error"].is_string());
    CHECK(drive_status(rcand)["moving"] == false);
    CHECK(nav_status(rcand)["running"] == false);
  }
}

TEST_CASE("nav: an obstacle below agent.min_obstacle_m latches the e-stop, before or during a job, and is audited") {
  auto config = nav_config();
  config["agent"] = {{"min_obstacle_m", 0.3}};
  SUBCASE("appearing mid-job") {
    // The double reports 200 cm, then 10 cm from its 4th read: one check before the job, then every 50 ms.
    config["drivers"].push_back({{"id", "depth0"}, {"protocol", "org.rcand.test.obstacles"}, {"nearest_cm", 200},
                                 {"then_cm", 10}, {"after_reads", 4}});
    RcandProcess rcand(config, {plugin_dir(), test_plugin_dir() / "obstacles"});
    int status = 0;
    auto answer = waypoint(rcand, 1.0, 90, 0.5, &status);
    REQUIRE(status == 200);
    const auto ended = wait_idle(rcand);
    CHECK(ended["result"]["reason"] == "obstacle");
    CHECK(ended["result"]["message"].get<std::string>().find("10.0 cm") != std::string::npos);
    CHECK(ended["elapsed_ms"].get<int>() < 1000);
    const auto estop = rcand.json("GET", "/api/estop", "guest-token");
    CHECK(estop["estopped"] == true);
    CHECK(estop["source"].get<std::string>().find("org.rcand.nav") != std::string::npos);
    CHECK(drive_status(rcand)["moving"] == false);
    const auto audit = rcand.json("GET", "/api/audit?limit=20", "owner-token")["entries"];
    bool found = false;
    for (const auto& entry : audit)
      if (entry["event"].get<std::string>().find("estop requested by plugin org.rcand.nav") != std::string::npos) {
        found = true;
        CHECK(entry["principal"] == "plugin:org.rcand.nav");
        CHECK(entry["outcome"] == "ok");
      }
    CHECK(found);
  }
  SUBCASE("already there: 423 and not a wheel moves") {
    config["drivers"].push_back({{"id", "depth0"}, {"protocol", "org.rcand.test.obstacles"}, {"nearest_cm", 12}});
    RcandProcess rcand(config, {plugin_dir(), test_plugin_dir() / "obstacles"});
    int status = 0;
    auto refused = waypoint(rcand, 1.0, 0, 0.5, &status);
    CHECK(status == 423);
    CHECK(refused["code"] == "ESTOP_ACTIVE");
    CHECK(drive_status(rcand)["commands"] == 0);
    CHECK(rcand.json("GET", "/api/estop", "guest-token")["estopped"] == true);
  }
}

TEST_CASE("nav: not advertised without the §10.2 physics fields, and then its endpoints reach no plugin") {
  auto config = sim_config();
  config["rcan_protocol"].erase("capabilities");  // auto-detection (§9.3)
  config["physics"].erase("turn_time_per_deg_s");
  RcandProcess rcand(config);
  CHECK(rcand.json("GET", "/api/discovery")["capabilities"] == json{"status", "teleop"});
  int status = 0;
  auto answer = waypoint(rcand, 1.0, 0, 0.5, &status);
  CHECK(status == 404);
  CHECK(answer["code"] == "CAPABILITY_NOT_FOUND");
  CHECK(drive_status(rcand)["commands"] == 0);
}
