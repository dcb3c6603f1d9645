// The arm's limit rules alone: range, step, speed, unknown joints, unreadable positions, and the config parser.
#include <doctest/doctest.h>

#include <cmath>
#include <string>

#include "arm_rules.hpp"
#include "joint_limits.hpp"

using nlohmann::json;
using rcand::plugins::arm::JointLimit;
using rcand::plugins::arm::MoveRequest;
using rcand::plugins::arm::parse_joint_limits;
using rcand::plugins::arm::plan_move;
using rcand::sdk::JointState;
using rcand::sdk::JointTarget;
using rcand::sdk::Response;

namespace {

std::vector<JointLimit> limits() {
  return parse_joint_limits(json::parse(R"([
    {"link": "base", "length_m": 0.1},
    {"joint": "shoulder", "min_deg": -90, "max_deg": 90, "max_velocity_dps": 60, "max_step_deg": 30},
    {"joint": "elbow", "min_deg": 0, "max_deg": 135}
  ])"),
                            "physics.kinematics");
}

MoveRequest move(std::vector<std::pair<std::string, double>> targets, std::optional<double> velocity_dps = std::nullopt) {
  MoveRequest request;
  request.targets = std::move(targets);
  request.velocity_dps = velocity_dps;
  return request;
}

std::vector<JointState> at(double shoulder, double elbow) {
  return {{"shoulder", shoulder, shoulder, 0, false, true}, {"elbow", elbow, elbow, 0, false, true}};
}

Response refused(const MoveRequest& request, const std::vector<JointState>& present = at(0, 0)) {
  auto plan = plan_move(request, limits(), present, "physics.kinematics");
  REQUIRE(std::holds_alternative<Response>(plan));
  return std::get<Response>(plan);
}

std::vector<JointTarget> planned(const MoveRequest& request, const std::vector<JointState>& present = at(0, 0)) {
  auto plan = plan_move(request, limits(), present, "physics.kinematics");
  REQUIRE(std::holds_alternative<std::vector<JointTarget>>(plan));
  return std::get<std::vector<JointTarget>>(plan);
}

}  // namespace

TEST_CASE("joint limits: links are skipped, defaults filled, bad items named by path") {
  const auto l = limits();
  REQUIRE(l.size() == 2);
  CHECK(l[0].joint == "shoulder");
  CHECK(l[0].max_step_deg == 30);
  CHECK(l[1].max_velocity_dps == JointLimit::kDefaultVelocityDps);
  CHECK(l[1].max_step_deg == JointLimit::kDefaultStepDeg);
  CHECK(l[1].home_deg == 0);

  auto error_of = [](const char* text) {
    try {
      parse_joint_limits(json::parse(text), "physics.kinematics");
    } catch (const rcand::sdk::ConfigError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  CHECK(error_of(R"([{"joint": "a", "max_deg": 1}])") ==
        "physics.kinematics[0].min_deg: required for joint 'a' (its lower limit in degrees)");
  CHECK(error_of(R"([{"joint": "a", "min_deg": 5, "max_deg": 5}])").find("needs min_deg < max_deg") != std::string::npos);
  CHECK(error_of(R"([{"joint": "a", "min_deg": 0, "max_deg": "9"}])") ==
        "physics.kinematics[0].max_deg: expected a number, found \"9\"");
  CHECK(error_of(R"([{"joint": "a", "min_deg": 0, "max_deg": 9, "max_step_deg": 0}])") ==
        "physics.kinematics[0].max_step_deg: expected a number > 0, found 0.0");
  CHECK(error_of(R"([{"joint": "a", "min_deg": 10, "max_deg": 20, "home_deg": 30}])").find("home_deg: 30") != std::string::npos);
  CHECK(error_of(R"([{"joint": "a", "min_deg": 0, "max_deg": 1}, {"joint": "a", "min_deg": 0, "max_deg": 1}])") ==
        "physics.kinematics[1].joint: joint 'a' is listed twice");
  CHECK(error_of(R"([{"joint": 7}])") == "physics.kinematics[0].joint: expected a non-empty string, found 7");
  CHECK(error_of(R"({"joint": "a"})").find("expected a list of joints") != std::string::npos);
  // A home outside a range that excludes 0 is refused; the default home is 0 clamped into the range.
  CHECK(parse_joint_limits(json::parse(R"([{"joint": "g", "min_deg": 10, "max_deg": 60}])"), "x")[0].home_deg == 10);
}

TEST_CASE("a target inside the limits and the step is planned at the joint's speed limit") {
  const auto targets = planned(move({{"shoulder", 30.0}, {"elbow", 45.0}}));
  REQUIRE(targets.size() == 2);
  CHECK(targets[0].joint == "shoulder");
  CHECK(targets[0].position_deg == 30);
  CHECK(targets[0].velocity_dps == 60);
  CHECK(targets[1].velocity_dps == JointLimit::kDefaultVelocityDps);
  CHECK(rcand::plugins::arm::eta_ms(targets, at(0, 0)) == 500);  // 30 deg at 60 dps, 45 deg at 90 dps
}

TEST_CASE("out of range is a 400 naming the joint and the limit, never clamped") {
  auto r = refused(move({{"elbow", 136.0}}), at(0, 130));
  CHECK(r.status == 400);
  CHECK(r.body["field"] == "joints.elbow");
  CHECK(r.body["joint"] == "elbow");
  CHECK(r.body["limit"] == "max_deg");
  CHECK(r.body["limit_value"] == 135);
  CHECK(r.body["error"] == "joint 'elbow' target 136 deg is above its limit max_deg 135 (range [0, 135], physics.kinematics)");
  r = refused(move({{"shoulder", -90.5}}), at(-80, 0));
  CHECK(r.body["limit"] == "min_deg");
  CHECK(r.body["error"].get<std::string>().find("below its limit min_deg -90") != std::string::npos);
}

TEST_CASE("the step cap is measured from the present position") {
  auto r = refused(move({{"shoulder", 31.0}}), at(0, 0));
  CHECK(r.status == 400);
  CHECK(r.body["limit"] == "max_step_deg");
  CHECK(r.body["limit_value"] == 30);
  CHECK(r.body["error"] ==
        "joint 'shoulder' would move 31 deg (from 0 to 31); its limit max_step_deg is 30 per command: move in smaller steps");
  CHECK(planned(move({{"shoulder", 31.0}}), at(1, 0)).size() == 1);  // the same target from nearer is fine
  CHECK(planned(move({{"shoulder", 30.0}}), at(0, 0)).size() == 1);  // exactly the cap is allowed
  MoveRequest grip = move({{"elbow", 135.0}});
  grip.cap_step = false;
  CHECK(planned(grip).size() == 1);  // grip is exempt from the step cap
}

TEST_CASE("a speed above any moved joint's limit is refused naming that joint") {
  auto r = refused(move({{"elbow", 10.0}, {"shoulder", 10.0}}, 70.0));
  CHECK(r.body["field"] == "velocity_dps");
  CHECK(r.body["joint"] == "shoulder");
  CHECK(r.body["limit"] == "max_velocity_dps");
  CHECK(planned(move({{"elbow", 10.0}, {"shoulder", 10.0}}, 20.0))[1].velocity_dps == 20);
  CHECK(refused(move({{"elbow", 10.0}}, 0.0)).body["field"] == "velocity_dps");
  CHECK(refused(move({{"elbow", 10.0}}, -5.0)).body["field"] == "velocity_dps");
}

TEST_CASE("unknown joints, missing driver joints and unreadable positions are refused before anything moves") {
  auto r = refused(move({{"wrist", 0.0}}));
  CHECK(r.status == 400);
  CHECK(r.body["field"] == "joints.wrist");
  CHECK(r.body["allowed"] == json{"shoulder", "elbow"});
  r = refused(move({{"elbow", 10.0}}), {{"shoulder", 0.0, 0, 0, false, true}});
  CHECK(r.status == 503);
  CHECK(r.body["joint"] == "elbow");
  r = refused(move({{"elbow", 10.0}}), {{"shoulder", 0.0, 0, 0, false, true}, {"elbow", std::nullopt, 0, 0, false, true}});
  CHECK(r.status == 503);
  CHECK(r.body["error"].get<std::string>().find("could not be read") != std::string::npos);
  CHECK(refused(move({{"elbow", std::nan("")}})).body["field"] == "joints.elbow");
  CHECK(refused(MoveRequest{}).body["field"] == "joints");
}

TEST_CASE("a speed below the slowest allowed is refused: 1e-300 deg/s would make an endless move") {
  for (const double slow : {1e-300, 1e-9, 0.5, std::nextafter(JointLimit::kMinVelocityDps, 0.0)}) {
    CAPTURE(slow);
    const auto r = refused(move({{"elbow", 10.0}}, slow));
    CHECK(r.status == 400);
    CHECK(r.body["field"] == "velocity_dps");
    CHECK(r.body["limit"] == "min_velocity_dps");
    CHECK(r.body["limit_value"] == JointLimit::kMinVelocityDps);
  }
  CHECK(refused(move({{"elbow", 10.0}}, std::nan(""))).body["limit"] == "min_velocity_dps");
  CHECK(refused(move({{"elbow", 10.0}}, HUGE_VAL)).body["limit"] == "max_velocity_dps");
  const auto slowest = planned(move({{"elbow", 10.0}}, JointLimit::kMinVelocityDps));
  CHECK(rcand::plugins::arm::eta_ms(slowest, at(0, 0)) == 10'000);
}

TEST_CASE("eta_ms saturates instead of converting an out-of-range double to an integer") {
  using rcand::plugins::arm::eta_ms;
  using rcand::plugins::arm::kMaxEtaMs;
  CHECK(eta_ms({{"elbow", 10.0, 1e-300}}, at(0, 0)) == kMaxEtaMs);
  CHECK(eta_ms({{"elbow", 1e308, 1.0}}, {{"elbow", -1e308, -1e308, 0, false, true}}) == kMaxEtaMs);  // the distance is inf
  CHECK(eta_ms({{"elbow", 10.0, 1.0}}, {{"elbow", std::nan(""), 0, 0, false, true}}) == 0);          // unreadable: no estimate
  CHECK(eta_ms({{"elbow", 10.0, 0.0}}, at(0, 0)) == 0);                                              // no speed: no estimate
  CHECK(eta_ms({{"elbow", 10.0, 1.0}}, at(0, 0)) == 10'000);
}

TEST_CASE("a position the driver reports as NaN or infinite is unreadable: the joint is not moved") {
  for (const double bad : {std::nan(""), HUGE_VAL, -HUGE_VAL}) {
    const auto r = refused(move({{"elbow", 10.0}}), {{"shoulder", 0.0, 0, 0, false, true}, {"elbow", bad, 0, 0, false, true}});
    CHECK(r.status == 503);
    CHECK(r.body["error"].get<std::string>().find("could not be read") != std::string::npos);
  }
}

TEST_CASE("an unknown joint's name is quoted cut to 200 bytes with its control characters replaced") {
  std::string name(1 << 20, 'j');
  name.replace(0, 8, "\x1b[2J\r\n\xe2\x80\xae");
  const auto r = refused(move({{name, 10.0}}));
  CHECK(r.status == 400);
  const std::string error = r.body["error"], field = r.body["field"];
  CHECK(error.size() <= 250);
  CHECK(field.size() <= 210);
  for (const std::string& text : {error, field}) {
    CHECK(text.find('\x1b') == std::string::npos);
    CHECK(text.find('\n') == std::string::npos);
    CHECK(text.find("\xe2\x80\xae") == std::string::npos);
  }
  CHECK(error.rfind("unknown joint '?[2J???", 0) == 0);
}

TEST_CASE("a joint's max_velocity_dps below the slowest speed a command may ask for is a config error") {
  try {
    parse_joint_limits(json::parse(R"([{"joint": "a", "min_deg": 0, "max_deg": 9, "max_velocity_dps": 0.5}])"),
                       "physics.kinematics");
    FAIL("accepted");
  } catch (const rcand::sdk::ConfigError& e) {
    CHECK(std::string(e.what()).find("physics.kinematics[0].max_velocity_dps: 0.5 is below") == 0);
  }
}
