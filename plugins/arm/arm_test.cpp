// The arm capability on the fake host, driving sim_arm through the motion gate: poses, grip, limits, step and speed
// caps, the e-stop, bad input, and an arm offered by a driver whose primary interface is something else.
#include <doctest/doctest.h>

#include <rcand/sdk/testing/fake_host.hpp>

#include <chrono>

#include "arm.hpp"
#include "arm_test_manifest.hpp"
#include "sim_arm.hpp"

extern "C" const rcand_plugin_descriptor* RCAND_ENTRY_FUNCTION(void);

using namespace std::chrono_literals;
using nlohmann::json;
using rcand::plugins::arm::ArmCapability;
using rcand::plugins::arm::SimArm;
using rcand::sdk::Response;
using rcand::sdk::Role;
using rcand::sdk::testing::FakeHost;
using rcand::sdk::testing::HostError;

namespace {

json robot() {
  return json::parse(R"({
    "physics": {"kinematics": [
      {"link": "base", "length_m": 0.1},
      {"joint": "shoulder", "min_deg": -90, "max_deg": 90, "max_velocity_dps": 60, "max_step_deg": 45},
      {"joint": "elbow", "min_deg": 0, "max_deg": 135, "home_deg": 90},
      {"joint": "gripper", "min_deg": 0, "max_deg": 60, "max_velocity_dps": 120, "max_step_deg": 10}
    ]},
    "runtime": {"capabilities": {"arm": {
      "gripper_joint": "gripper",
      "poses": {"ready": {"shoulder": 30, "elbow": 60}, "rest": {"shoulder": 0, "elbow": 90}}
    }}}
  })");
}

struct Fixture {
  FakeHost host;
  explicit Fixture(json config = robot()) : host(config) {
    host.load(RCAND_ENTRY_FUNCTION, arm_manifest());
    host.add_driver("arm0", "sim_arm");
    host.add_capability("arm");
  }
  SimArm& sim() { return host.driver<SimArm>("arm0"); }
  Response action(json body, Role role = Role::User) { return host.call("POST", "/api/action", std::move(body), role); }
  double at(std::size_t joint) { return *sim().joint_states().at(joint).position_deg; }
  Response joints() { return host.call("GET", "/api/arm/joints", nullptr, Role::Guest); }
};

}  // namespace

TEST_CASE("arm_pose with named joints moves them at their speed limit and answers the plan") {
  Fixture f;
  auto r = f.action({{"type", "arm_pose"}, {"joints", {{"shoulder", 45}, {"elbow", 45}}}});
  REQUIRE(r.status == 200);
  CHECK(r.body["ok"] == true);
  CHECK(r.body["driver"] == "arm0");
  CHECK(r.body["targets"] == json{{"shoulder", 45.0}, {"elbow", 45.0}});
  CHECK(r.body["velocity_dps"] == json{{"shoulder", 60.0}, {"elbow", 90.0}});
  CHECK(r.body["eta_ms"] == 750);  // shoulder: 45 deg at 60 dps
  f.host.advance(500ms);
  CHECK(f.at(0) == doctest::Approx(30));
  CHECK(f.at(1) == doctest::Approx(45));
  f.host.advance(250ms);
  CHECK(f.at(0) == doctest::Approx(45));
  CHECK(f.sim().commands() == 1);

  // A slower speed for every joint.
  r = f.action({{"type", "arm_pose"}, {"joints", {{"shoulder", 15}}}, {"velocity_dps", 30}});
  REQUIRE(r.status == 200);
  CHECK(r.body["eta_ms"] == 1000);
}

TEST_CASE("limits: out of range, too big a step and too fast are 400s naming joint and limit; the driver gets nothing") {
  Fixture f;
  auto r = f.action({{"type", "arm_pose"}, {"joints", {{"elbow", 140}}}});
  CHECK(r.status == 400);
  CHECK(r.body["code"] == "BAD_REQUEST");
  CHECK(r.body["joint"] == "elbow");
  CHECK(r.body["limit"] == "max_deg");
  CHECK(r.body["error"].get<std::string>().find("elbow") != std::string::npos);

  r = f.action({{"type", "arm_pose"}, {"joints", {{"shoulder", 50}}}});  // 50 > max_step_deg 45
  CHECK(r.status == 400);
  CHECK(r.body["limit"] == "max_step_deg");
  CHECK(r.body["error"] ==
        "joint 'shoulder' would move 50 deg (from 0 to 50); its limit max_step_deg is 45 per command: move in smaller steps");

  r = f.action({{"type", "arm_pose"}, {"joints", {{"shoulder", 10}, {"elbow", 80}}}, {"velocity_dps", 80}});
  CHECK(r.status == 400);
  CHECK(r.body["field"] == "velocity_dps");
  CHECK(r.body["joint"] == "shoulder");
  CHECK(r.body["limit_value"] == 60);

  // One bad joint refuses the whole command: the good one does not move either.
  r = f.action({{"type", "arm_pose"}, {"joints", {{"elbow", 80}, {"shoulder", -91}}}});
  CHECK(r.status == 400);
  CHECK(r.body["limit"] == "min_deg");
  CHECK(f.sim().commands() == 0);
  CHECK(f.at(1) == 90);
}

TEST_CASE("named poses from config, checked at startup; unknown names list the known ones") {
  Fixture f;
  auto r = f.action({{"type", "arm_pose"}, {"pose", "ready"}});
  REQUIRE(r.status == 200);
  CHECK(r.body["pose"] == "ready");
  f.host.advance(2s);
  CHECK(f.at(0) == doctest::Approx(30));
  CHECK(f.at(1) == doctest::Approx(60));

  r = f.action({{"type", "arm_pose"}, {"pose", "dance"}});
  CHECK(r.status == 400);
  CHECK(r.body["field"] == "pose");
  CHECK(r.body["allowed"] == json{"ready", "rest"});

  json bad = robot();
  bad["runtime"]["capabilities"]["arm"]["poses"]["wild"] = {{"elbow", 200}};
  FakeHost host(bad);
  host.load(RCAND_ENTRY_FUNCTION, arm_manifest());
  host.add_driver("arm0", "sim_arm");
  CHECK_THROWS_WITH_AS(host.add_capability("arm"),
                       doctest::Contains("poses.wild.elbow: 200 is outside the joint's range [0, 135]"), HostError);
  bad = robot();
  bad["runtime"]["capabilities"]["arm"]["poses"]["typo"] = {{"elbw", 10}};
  FakeHost host2(bad);
  host2.load(RCAND_ENTRY_FUNCTION, arm_manifest());
  CHECK_THROWS_WITH_AS(host2.add_capability("arm"), doctest::Contains("poses.typo.elbw: no joint 'elbw'"), HostError);
}

TEST_CASE("grip opens and closes the gripper joint across its whole range") {
  Fixture f;
  auto r = f.action({{"type", "grip"}, {"state", "open"}});
  REQUIRE(r.status == 200);
  CHECK(r.body["targets"] == json{{"gripper", 60.0}});
  f.host.advance(1s);
  CHECK(f.at(2) == doctest::Approx(60));
  r = f.action({{"type", "grip"}, {"state", "close"}});
  REQUIRE(r.status == 200);
  f.host.advance(1s);
  CHECK(f.at(2) == doctest::Approx(0));
  // The step cap applies to arm_pose on the gripper joint, not to grip.
  CHECK(f.action({{"type", "arm_pose"}, {"joints", {{"gripper", 60}}}}).body["limit"] == "max_step_deg");

  CHECK(f.action({{"type", "grip"}, {"state", "half"}}).body["allowed"] == json{"open", "close"});
  CHECK(f.action({{"type", "grip"}}).body["field"] == "state");

  json no_gripper = robot();
  no_gripper["runtime"]["capabilities"]["arm"].erase("gripper_joint");
  Fixture g(no_gripper);
  r = g.action({{"type", "grip"}, {"state", "open"}});
  CHECK(r.status == 400);
  CHECK(r.body["error"].get<std::string>().find("gripper_joint") != std::string::npos);
}

TEST_CASE("e-stop: arm actions are refused with 423, the arm holds its pose with torque on") {
  Fixture f;
  REQUIRE(f.action({{"type", "arm_pose"}, {"joints", {{"shoulder", 40}}}}).status == 200);
  f.host.advance(500ms);
  f.host.latch_estop("test");
  f.host.advance(2s);
  CHECK(f.at(0) == doctest::Approx(30));
  const auto states = f.sim().joint_states();
  for (const auto& s : states) CHECK(s.torque_on);
  auto r = f.action({{"type", "arm_pose"}, {"joints", {{"shoulder", 20}}}});
  CHECK(r.status == 423);
  CHECK(r.body["code"] == "ESTOP_ACTIVE");
  CHECK(f.action({{"type", "grip"}, {"state", "open"}}).status == 423);
  CHECK(f.sim().commands() == 1);
  CHECK(f.host.last_published_status("arm")->at("estops") == 1);
  // Reading the joints is never refused.
  CHECK(f.joints().status == 200);
}

TEST_CASE("bad bodies are 400s naming the field; roles below user are 403") {
  Fixture f;
  CHECK(f.action({{"type", "arm_pose"}}).body["field"] == "pose");
  CHECK(f.action({{"type", "arm_pose"}, {"pose", "ready"}, {"joints", {{"elbow", 1}}}}).body["field"] == "joints");
  CHECK(f.action({{"type", "arm_pose"}, {"joints", json::array()}}).body["field"] == "joints");
  CHECK(f.action({{"type", "arm_pose"}, {"joints", json::object()}}).body["field"] == "joints");
  CHECK(f.action({{"type", "arm_pose"}, {"joints", {{"elbow", "90"}}}}).body["field"] == "joints.elbow");
  CHECK(f.action({{"type", "arm_pose"}, {"joints", {{"wrist", 1}}}}).body["allowed"] == json{"shoulder", "elbow", "gripper"});
  CHECK(f.action({{"type", "arm_pose"}, {"joints", {{"elbow", 80}}}, {"velocity_dps", "fast"}}).body["field"] == "velocity_dps");
  CHECK(f.action({{"type", "arm_pose"}, {"pose", 7}}).body["field"] == "pose");
  CHECK(f.action({{"type", "arm_pose"}, {"joints", {{"elbow", 80}}}}, Role::Guest).status == 403);
  CHECK(f.sim().commands() == 0);
}

TEST_CASE("velocity_dps: 1e-300 and anything below 1 deg/s are refused; nothing reaches the driver") {
  Fixture f;
  for (const double slow : {1e-300, 4.9e-324, 0.25}) {
    CAPTURE(slow);
    const auto r = f.action({{"type", "arm_pose"}, {"joints", {{"shoulder", 45}}}, {"velocity_dps", slow}});
    CHECK(r.status == 400);
    CHECK(r.body["field"] == "velocity_dps");
    CHECK(r.body["limit"] == "min_velocity_dps");
  }
  const auto huge = f.action({{"type", "arm_pose"}, {"joints", {{"shoulder", 45}}}, {"velocity_dps", 1e308}});
  CHECK(huge.status == 400);
  CHECK(huge.body["limit"] == "max_velocity_dps");
  CHECK(f.sim().commands() == 0);
  const auto slowest = f.action({{"type", "arm_pose"}, {"joints", {{"shoulder", 45}}}, {"velocity_dps", 1}});
  REQUIRE(slowest.status == 200);
  CHECK(slowest.body["eta_ms"] == 45'000);
}

TEST_CASE("an unknown pose or joint name of 1 MiB is quoted back cut to 200 bytes, its controls replaced") {
  Fixture f;
  std::string name(1 << 20, 'p');
  name.replace(0, 9, "\x1b[31m\n\xc2\x9b\xe2\x80\xae");
  const auto pose = f.action({{"type", "arm_pose"}, {"pose", name}});
  const auto joint = f.action({{"type", "arm_pose"}, {"joints", {{name, 10}}}});
  const auto typed = f.action({{"type", "arm_pose"}, {"joints", {{name, "ten"}}}});
  const auto grip = f.action({{"type", "grip"}, {"state", name}});
  for (const auto& r : {pose, joint, typed, grip}) {
    CHECK(r.status == 400);
    const std::string answer = r.body.dump();
    CAPTURE(answer.substr(0, 300));
    CHECK(answer.size() < 1000);
    for (const char* forbidden : {"\\u001b", "\\n", "\xc2\x9b", "\xe2\x80\xae", "\\u009b"})
      CHECK(answer.find(forbidden) == std::string::npos);
    CHECK(answer.find("?[31m???") != std::string::npos);
  }
  CHECK(pose.body["error"].get<std::string>().rfind("unknown pose '?[31m???pppp", 0) == 0);
  CHECK(joint.body["field"].get<std::string>().rfind("joints.?[31m???ppp", 0) == 0);
  CHECK(f.sim().commands() == 0);
}

TEST_CASE("GET /api/arm/joints: live positions, targets, limits and poses") {
  Fixture f;
  REQUIRE(f.action({{"type", "arm_pose"}, {"joints", {{"shoulder", 30}}}}).status == 200);
  f.host.advance(250ms);
  auto r = f.joints();
  REQUIRE(r.status == 200);
  CHECK(r.body["driver"] == "arm0");
  CHECK(r.body["limits_from"] == "physics.kinematics");
  const json& shoulder = r.body["joints"][0];
  CHECK(shoulder["joint"] == "shoulder");
  CHECK(shoulder["position_deg"].get<double>() == doctest::Approx(15));
  CHECK(shoulder["target_deg"] == 30.0);
  CHECK(shoulder["moving"] == true);
  CHECK(shoulder["torque_on"] == true);
  CHECK(shoulder["limits"]["max_step_deg"] == 45.0);
  CHECK(r.body["poses"]["ready"] == json{{"shoulder", 30.0}, {"elbow", 60.0}});
  CHECK(r.body["gripper_joint"] == "gripper");
}

TEST_CASE("limits from the driver's joints block when physics.kinematics names no joint; none at all fails the capability") {
  json config = json::parse(R"({"drivers": [{"id": "arm0", "protocol": "sim_arm",
                                "joints": [{"joint": "pan", "min_deg": -45, "max_deg": 45}]}]})");
  FakeHost host(config);
  host.load(RCAND_ENTRY_FUNCTION, arm_manifest());
  host.add_driver("arm0", "sim_arm", {{"joints", config["drivers"][0]["joints"]}});
  host.add_capability("arm");
  auto r = host.call("POST", "/api/action", {{"type", "arm_pose"}, {"joints", {{"pan", 50}}}});
  CHECK(r.status == 400);
  CHECK(r.body["error"].get<std::string>().find("drivers[arm0].joints") != std::string::npos);

  FakeHost bare(json::parse(R"({"physics": {"kinematics": [{"link": "base"}]}})"));
  bare.load(RCAND_ENTRY_FUNCTION, arm_manifest());
  CHECK_THROWS_WITH_AS(bare.add_capability("arm"), doctest::Contains("no joint limits"), HostError);
}

namespace {

// A wheeled base that also carries two servos (as a PCA9685 board may): its primary interface is
// differential_drive, and the arm reaches its joints by cross-casting. Its elbow reports an unreadable position.
class DriveWithServos final : public rcand::sdk::DifferentialDrive, public rcand::sdk::JointArm {
 public:
  void set_wheel_speeds(double, double) override {}
  void halt() noexcept override { ++halts; }
  void set_joint_targets(const std::vector<rcand::sdk::JointTarget>& t) override { sent.insert(sent.end(), t.begin(), t.end()); }
  std::vector<rcand::sdk::JointState> joint_states() const override {
    return {{"shoulder", 0.0, 0.0, 0.0, false, true}, {"elbow", std::nullopt, 0.0, 0.0, false, true}};
  }
  std::vector<rcand::sdk::JointTarget> sent;
  int halts = 0;
};

}  // namespace

TEST_CASE("an arm offered by a driver with another primary interface; an unreadable joint is never moved") {
  FakeHost host(robot());
  host.load(RCAND_ENTRY_FUNCTION, arm_manifest());
  auto& base = host.add_driver_instance<DriveWithServos>("base");
  host.add_capability("arm");
  auto r = host.call("POST", "/api/action", {{"type", "arm_pose"}, {"joints", {{"shoulder", 20}}}}, Role::User);
  REQUIRE(r.status == 200);
  CHECK(r.body["driver"] == "base");
  REQUIRE(base.sent.size() == 1);
  CHECK(base.sent[0].position_deg == 20);

  r = host.call("POST", "/api/action", {{"type", "arm_pose"}, {"joints", {{"elbow", 20}}}}, Role::User);
  CHECK(r.status == 503);
  CHECK(r.body["joint"] == "elbow");
  CHECK(base.sent.size() == 1);

  CHECK(host.call("POST", "/api/action", {{"type", "grip"}, {"state", "open"}}).status == 503);  // no gripper joint here
}

TEST_CASE("no arm actuator: 503 UNAVAILABLE, not a crash") {
  FakeHost host(robot());
  host.load(RCAND_ENTRY_FUNCTION, arm_manifest());
  host.add_capability("arm");
  auto r = host.call("POST", "/api/action", {{"type", "arm_pose"}, {"pose", "rest"}});
  CHECK(r.status == 503);
  CHECK(r.body["code"] == "UNAVAILABLE");
}
