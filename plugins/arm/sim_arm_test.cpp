// sim_arm on the fake host: joints travel at their speed on the clock, halt holds the pose with torque on, and a
// bad command is refused whole.
#include <doctest/doctest.h>

#include <rcand/sdk/testing/fake_host.hpp>

#include <chrono>

#include "arm_test_manifest.hpp"
#include "sim_arm.hpp"

extern "C" const rcand_plugin_descriptor* RCAND_ENTRY_FUNCTION(void);

using namespace std::chrono_literals;
using nlohmann::json;
using rcand::plugins::arm::SimArm;
using rcand::sdk::GateStatus;
using rcand::sdk::JointArm;
using rcand::sdk::JointTarget;
using rcand::sdk::testing::FakeHost;
using rcand::sdk::testing::HostError;

namespace {

json two_joints() {
  return json::parse(R"([{"joint": "shoulder", "min_deg": -90, "max_deg": 90, "max_velocity_dps": 60},
                         {"joint": "elbow", "min_deg": 0, "max_deg": 135, "home_deg": 90}])");
}

GateStatus command(FakeHost& host, std::vector<JointTarget> targets) {
  return host.motion().actuate_as<JointArm>("arm0", [&](JointArm& arm) { arm.set_joint_targets(targets); });
}

double position(FakeHost& host, std::size_t joint) { return *host.driver<SimArm>("arm0").joint_states().at(joint).position_deg; }

}  // namespace

TEST_CASE("sim_arm: manifest matches, interface joint_arm, joints from the driver block or physics.kinematics") {
  {
    FakeHost host;
    host.load(RCAND_ENTRY_FUNCTION, arm_manifest());
    host.add_driver("arm0", "sim_arm", {{"joints", two_joints()}});
    const auto actuators = host.motion().actuators();
    REQUIRE(actuators.size() == 1);
    CHECK(actuators[0].interface == "joint_arm");
    CHECK(position(host, 0) == 0);
    CHECK(position(host, 1) == 90);  // home_deg
  }
  {
    FakeHost host({{"physics", {{"kinematics", two_joints()}}}});
    host.load(RCAND_ENTRY_FUNCTION, arm_manifest());
    host.add_driver("arm0", "sim_arm");
    CHECK(host.driver<SimArm>("arm0").joints().size() == 2);
  }
  {
    FakeHost host;
    host.load(RCAND_ENTRY_FUNCTION, arm_manifest());
    CHECK_THROWS_WITH_AS(host.add_driver("arm0", "sim_arm"), doctest::Contains("no joints"), HostError);
    CHECK_THROWS_WITH_AS(host.add_driver("arm1", "sim_arm", {{"joints", json::parse(R"([{"joint": "a", "min_deg": 1}])")}}),
                         doctest::Contains("joints[0].max_deg: required"), HostError);
  }
}

TEST_CASE("sim_arm: joints travel at their commanded speed, capped by their rating") {
  FakeHost host;
  host.load(RCAND_ENTRY_FUNCTION, arm_manifest());
  host.add_driver("arm0", "sim_arm", {{"joints", two_joints()}});
  // shoulder asks 120 dps but is rated 60; elbow goes down at 45 dps.
  REQUIRE(command(host, {{"shoulder", 30, 120}, {"elbow", 45, 45}}) == GateStatus::Ok);
  host.advance(250ms);
  CHECK(position(host, 0) == doctest::Approx(15));
  CHECK(position(host, 1) == doctest::Approx(90 - 11.25));
  host.advance(250ms);
  CHECK(position(host, 0) == doctest::Approx(30));
  const auto states = host.driver<SimArm>("arm0").joint_states();
  CHECK_FALSE(states[0].moving);
  CHECK(states[1].moving);
  CHECK(states[1].torque_on);
  host.advance(1s);
  CHECK(position(host, 1) == doctest::Approx(45));
  CHECK_FALSE(host.driver<SimArm>("arm0").status()["moving"].get<bool>());
}

TEST_CASE("sim_arm: halt holds the present pose with torque on, and the e-stop halts it through the gate") {
  FakeHost host;
  host.load(RCAND_ENTRY_FUNCTION, arm_manifest());
  host.add_driver("arm0", "sim_arm", {{"joints", two_joints()}});
  auto& sim = host.driver<SimArm>("arm0");
  REQUIRE(command(host, {{"shoulder", 60, 60}}) == GateStatus::Ok);
  host.advance(500ms);
  host.latch_estop("test");
  CHECK(sim.halts() == 1);
  host.advance(2s);
  const auto states = sim.joint_states();
  CHECK(*states[0].position_deg == doctest::Approx(30));  // stopped half-way, and stays there
  CHECK(states[0].target_deg == doctest::Approx(30));
  CHECK(states[0].torque_on);
  CHECK_FALSE(states[0].moving);
  CHECK(command(host, {{"shoulder", 0, 60}}) == GateStatus::EstopActive);
  CHECK(sim.commands() == 1);
  const auto timeline = sim.timeline();
  REQUIRE(timeline.size() == 2);
  CHECK(timeline[1].cause == "halt");
  CHECK(timeline[1].positions_deg[0] == doctest::Approx(30));
}

TEST_CASE("sim_arm: an invalid command is refused whole and nothing moves") {
  rcand::sdk::testing::ManualClock clock;
  SimArm arm(clock, rcand::plugins::arm::parse_joint_limits(two_joints(), "joints"));
  CHECK_THROWS_AS(arm.set_joint_targets({{"shoulder", 10, 10}, {"wrist", 0, 10}}), std::invalid_argument);
  CHECK_THROWS_AS(arm.set_joint_targets({{"shoulder", 10, 10}, {"elbow", 200, 10}}), std::invalid_argument);
  CHECK_THROWS_AS(arm.set_joint_targets({{"shoulder", 10, 0}}), std::invalid_argument);
  CHECK(arm.joint_states()[0].target_deg == 0);
  CHECK(arm.commands() == 0);
}

TEST_CASE("sim_arm: status is published while a joint moves and once more at rest") {
  FakeHost host;
  host.load(RCAND_ENTRY_FUNCTION, arm_manifest());
  host.add_driver("arm0", "sim_arm", {{"joints", two_joints()}});
  REQUIRE(command(host, {{"shoulder", 30, 60}}) == GateStatus::Ok);
  host.advance(1s);
  const auto published = host.published_statuses("arm0");
  REQUIRE(published.size() >= 5);
  CHECK(published.front()["moving"] == true);
  CHECK(published.back()["moving"] == false);
  CHECK(published.back()["joints"][0]["position_deg"] == 30.0);
  CHECK(host.pending_tasks() == 0);
}
