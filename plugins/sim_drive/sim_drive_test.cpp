// sim_drive on the fake host: timeline, clamping, pose integration, halt, and the fault-injection drills.
#include <doctest/doctest.h>

#include <rcand/sdk/testing/fake_host.hpp>

#include <chrono>
#include <cmath>
#include <fstream>
#include <numbers>

#include "sim_drive.hpp"

extern "C" const rcand_plugin_descriptor* RCAND_ENTRY_FUNCTION(void);

using namespace std::chrono_literals;
using rcand::plugins::sim_drive::SimDrive;
using rcand::sdk::DifferentialDrive;
using rcand::sdk::GateStatus;
using rcand::sdk::testing::FakeHost;
using rcand::sdk::testing::HostError;

namespace {

nlohmann::json manifest() {
  std::ifstream in(RCAND_SOURCE_DIR "/manifests/sim_drive.json");
  REQUIRE(in.good());
  return nlohmann::json::parse(in);
}

GateStatus drive(FakeHost& host, double left, double right, const char* id = "base") {
  return host.motion().actuate_as<DifferentialDrive>(id, [&](DifferentialDrive& d) { d.set_wheel_speeds(left, right); });
}

}  // namespace

TEST_CASE("the manifest matches the registration and the driver is an actuating differential_drive") {
  FakeHost host;
  host.load(RCAND_ENTRY_FUNCTION, manifest());
  host.add_driver("base", "sim_diff_drive");
  const auto actuators = host.motion().actuators();
  REQUIRE(actuators.size() == 1);
  CHECK(actuators[0].id == "base");
  CHECK(actuators[0].interface == "differential_drive");
  CHECK(host.driver<SimDrive>("base").settings().wheel_circumference_m == doctest::Approx(0.21));
}

TEST_CASE("commands and halts land on the timeline with their time and cause") {
  FakeHost host;
  host.load(RCAND_ENTRY_FUNCTION, manifest());
  host.add_driver("base", "sim_diff_drive");
  auto& sim = host.driver<SimDrive>("base");

  host.advance(1000us);
  REQUIRE(drive(host, 0.5, -0.25) == GateStatus::Ok);
  host.advance(2000us);
  host.motion().halt("base");

  const auto timeline = sim.timeline();
  REQUIRE(timeline.size() == 2);
  CHECK(timeline[0].t_us == 1000);
  CHECK(timeline[0].left == 0.5);
  CHECK(timeline[0].right == -0.25);
  CHECK(timeline[0].cause == "command");
  CHECK(timeline[1].t_us == 3000);
  CHECK(timeline[1].left == 0.0);
  CHECK(timeline[1].cause == "halt");

  const auto status = sim.status();
  CHECK(status["commands"] == 1);
  CHECK(status["halts"] == 1);
  CHECK(status["moving"] == false);
  CHECK(status["zero_since_us"] == 3000);
  CHECK(status["now_us"] == 3000);
  REQUIRE(status["timeline"].size() == 2);
  CHECK(status["timeline"][1]["cause"] == "halt");
}

TEST_CASE("wheel speeds are clamped to [-1, 1]") {
  FakeHost host;
  host.load(RCAND_ENTRY_FUNCTION);
  host.add_driver("base", "sim_diff_drive");
  REQUIRE(drive(host, 2.5, -7.0) == GateStatus::Ok);
  auto& sim = host.driver<SimDrive>("base");
  CHECK(sim.left() == 1.0);
  CHECK(sim.right() == -1.0);
  CHECK(sim.timeline().back().left == 1.0);
  CHECK(sim.timeline().back().right == -1.0);
}

TEST_CASE("pose: one second at full speed moves circumference x rps metres") {
  SUBCASE("defaults") {
    FakeHost host;
    host.load(RCAND_ENTRY_FUNCTION);
    host.add_driver("base", "sim_diff_drive");
    REQUIRE(drive(host, 1.0, 1.0) == GateStatus::Ok);
    host.advance(1s);
    const auto pose = host.driver<SimDrive>("base").pose();
    CHECK(pose.x_m == doctest::Approx(0.21));
    CHECK(pose.y_m == doctest::Approx(0.0));
    CHECK(pose.heading_deg() == doctest::Approx(0.0));
    // Stopping freezes the pose.
    host.motion().halt("base");
    host.advance(5s);
    CHECK(host.driver<SimDrive>("base").status()["pose"]["x_m"].get<double>() == doctest::Approx(0.21));
  }
  SUBCASE("from the robot config's physics block") {
    FakeHost host({{"physics", {{"wheel_circumference_m", 0.3}, {"max_wheel_rps", 2.0}}}});
    host.load(RCAND_ENTRY_FUNCTION, manifest());
    host.add_driver("base", "sim_diff_drive");
    REQUIRE(drive(host, 1.0, 1.0) == GateStatus::Ok);
    host.advance(1s);
    CHECK(host.driver<SimDrive>("base").pose().x_m == doctest::Approx(0.6));
  }
  SUBCASE("the driver's own settings win over physics") {
    FakeHost host({{"physics", {{"wheel_circumference_m", 0.3}}}});
    host.load(RCAND_ENTRY_FUNCTION, manifest());
    host.add_driver("base", "sim_diff_drive", {{"wheel_circumference_m", 0.5}});
    REQUIRE(drive(host, -0.5, -0.5) == GateStatus::Ok);
    host.advance(2s);
    CHECK(host.driver<SimDrive>("base").pose().x_m == doctest::Approx(-0.5));
  }
}

TEST_CASE("pose: turning in place and driving an arc") {
  FakeHost host;
  host.load(RCAND_ENTRY_FUNCTION);
  host.add_driver("base", "sim_diff_drive");
  auto& sim = host.driver<SimDrive>("base");
  // Spinning left at full speed: omega = 2 * 0.21 / 0.15 rad/s; a quarter turn takes (pi/2) / omega seconds.
  const double omega = 2 * 0.21 / 0.15;
  REQUIRE(drive(host, -1.0, 1.0) == GateStatus::Ok);
  host.advance(std::chrono::microseconds(std::llround(std::numbers::pi / 2 / omega * 1e6)));
  CHECK(sim.pose().heading_deg() == doctest::Approx(90.0).epsilon(1e-4));
  CHECK(sim.pose().x_m == doctest::Approx(0.0));
  // Then straight ahead for one second: now along +y.
  REQUIRE(drive(host, 1.0, 1.0) == GateStatus::Ok);
  host.advance(1s);
  CHECK(sim.pose().x_m == doctest::Approx(0.0).epsilon(1e-4));
  CHECK(sim.pose().y_m == doctest::Approx(0.21).epsilon(1e-4));
  // A half turn more folds into (-180, 180].
  REQUIRE(drive(host, -1.0, 1.0) == GateStatus::Ok);
  host.advance(std::chrono::microseconds(std::llround(std::numbers::pi / omega * 1e6)));
  CHECK(sim.pose().heading_deg() == doctest::Approx(-90.0).epsilon(1e-4));
}

TEST_CASE("halt zeroes the wheels and records zero_since_us; status shows null while moving") {
  FakeHost host;
  host.load(RCAND_ENTRY_FUNCTION);
  host.add_driver("base", "sim_diff_drive");
  auto& sim = host.driver<SimDrive>("base");
  REQUIRE(drive(host, 0.3, 0.3) == GateStatus::Ok);
  CHECK(sim.status()["moving"] == true);
  CHECK(sim.status()["zero_since_us"].is_null());
  host.advance(250ms);
  host.latch_estop("test");  // the host halts every actuator
  CHECK(sim.left() == 0.0);
  CHECK(sim.right() == 0.0);
  CHECK(sim.halts() == 1);
  CHECK(sim.status()["zero_since_us"] == 250'000);
  // A second halt keeps the time the wheels first reached zero.
  host.advance(10ms);
  host.motion().halt("base");
  CHECK(sim.status()["zero_since_us"] == 250'000);
  CHECK(sim.halts() == 2);
}

TEST_CASE("the timeline keeps the newest 4096 events; status shows the newest 256") {
  FakeHost host;
  host.load(RCAND_ENTRY_FUNCTION);
  host.add_driver("base", "sim_diff_drive");
  auto& sim = host.driver<SimDrive>("base");
  for (int i = 0; i < 5000; ++i) {
    host.advance(1us);
    REQUIRE(drive(host, 0.1, 0.1) == GateStatus::Ok);
  }
  const auto timeline = sim.timeline();
  REQUIRE(timeline.size() == SimDrive::kTimelineCapacity);
  CHECK(timeline.front().t_us == 5000 - 4096 + 1);
  CHECK(timeline.back().t_us == 5000);
  const auto status = sim.status();
  REQUIRE(status["timeline"].size() == SimDrive::kStatusEvents);
  CHECK(status["timeline"].back()["t_us"] == 5000);
  CHECK(status["commands"] == 5000);
}

TEST_CASE("fail_after_commands: the Nth command throws, records nothing, and the gate marks the driver failed") {
  FakeHost host;
  host.load(RCAND_ENTRY_FUNCTION, manifest());
  host.add_driver("base", "sim_diff_drive", {{"fail_after_commands", 3}});
  auto& sim = host.driver<SimDrive>("base");
  CHECK(drive(host, 0.1, 0.1) == GateStatus::Ok);
  CHECK(drive(host, 0.2, 0.2) == GateStatus::Ok);
  CHECK(drive(host, 0.3, 0.3) == GateStatus::ActuatorFailed);
  CHECK(host.driver_failed("base"));
  CHECK(sim.commands() == 2);
  for (const auto& e : sim.timeline()) CHECK(e.left != 0.3);
  CHECK(sim.left() == 0.0);  // the gate halted the failed driver
  // Out of service from now on; stopping is still allowed.
  CHECK(drive(host, 0.1, 0.1) == GateStatus::ActuatorFailed);
  host.motion().halt("base");
  CHECK(sim.commands() == 2);

  // Calling the driver directly: the Nth call and later ones throw.
  CHECK_THROWS_AS(sim.set_wheel_speeds(0.5, 0.5), std::runtime_error);
}

TEST_CASE("halt_delay_ms: halt takes at least that long before the wheels read zero") {
  FakeHost host;
  host.load(RCAND_ENTRY_FUNCTION, manifest());
  host.add_driver("base", "sim_diff_drive", {{"halt_delay_ms", 20}});
  auto& sim = host.driver<SimDrive>("base");
  REQUIRE(drive(host, 1.0, 1.0) == GateStatus::Ok);
  const auto started = std::chrono::steady_clock::now();
  host.motion().halt("base");
  CHECK(std::chrono::steady_clock::now() - started >= 20ms);
  CHECK(sim.left() == 0.0);
}

TEST_CASE("bad settings are refused naming the key") {
  SUBCASE("by the plugin itself (no manifest checks)") {
    FakeHost host;
    host.load(RCAND_ENTRY_FUNCTION);
    try {
      host.add_driver("base", "sim_diff_drive", {{"wheel_base_m", -1.0}});
      FAIL("expected the factory to refuse");
    } catch (const HostError& e) {
      CHECK(std::string(e.what()).find("wheel_base_m") != std::string::npos);
    }
    try {
      host.add_driver("base2", "sim_diff_drive", {{"max_wheel_rps", "fast"}});
      FAIL("expected the factory to refuse");
    } catch (const HostError& e) {
      CHECK(std::string(e.what()).find("max_wheel_rps") != std::string::npos);
    }
    FakeHost physics_host({{"physics", {{"wheel_circumference_m", 0.0}}}});
    physics_host.load(RCAND_ENTRY_FUNCTION);
    CHECK_THROWS_WITH_AS(physics_host.add_driver("base", "sim_diff_drive"),
                         doctest::Contains("physics.wheel_circumference_m"), HostError);
  }
  SUBCASE("by the manifest schema") {
    FakeHost host;
    host.load(RCAND_ENTRY_FUNCTION, manifest());
    CHECK_THROWS_WITH_AS(host.add_driver("base", "sim_diff_drive", {{"halt_delay_ms", 1.5}}),
                         doctest::Contains("halt_delay_ms"), HostError);
    CHECK_THROWS_WITH_AS(host.add_driver("base", "sim_diff_drive", {{"wheel_bas_m", 0.2}}),
                         doctest::Contains("wheel_bas_m: unknown key"), HostError);
  }
}

TEST_CASE("the status is published from the status worker: at the first command, 10 Hz while moving, then the stop") {
  FakeHost host;
  host.load(RCAND_ENTRY_FUNCTION, manifest());
  host.add_driver("base", "sim_diff_drive");
  auto& sim = host.driver<SimDrive>("base");
  CHECK_FALSE(host.last_published_status("base"));

  REQUIRE(drive(host, 0.5, 0.5) == GateStatus::Ok);
  CHECK_FALSE(host.last_published_status("base"));  // not on the caller's thread: the worker publishes
  host.run_pending();
  REQUIRE(host.last_published_status("base"));
  auto without_timeline = sim.status();  // the timeline grows with every command: status() has it, a publish does not
  REQUIRE(without_timeline.contains("timeline"));
  without_timeline.erase("timeline");
  CHECK(*host.last_published_status("base") == without_timeline);
  CHECK((*host.last_published_status("base"))["moving"] == true);

  host.advance(350ms);  // the pose moves: one publish per 100 ms
  CHECK(host.published_statuses("base").size() == 4);
  CHECK((*host.last_published_status("base"))["now_us"] == 300'000);
  REQUIRE(drive(host, 0.2, 0.2) == GateStatus::Ok);  // already publishing: no extra one
  host.run_pending();
  CHECK(host.published_statuses("base").size() == 4);

  host.motion().halt("base");  // nothing on the stop path: the next tick publishes the stop, and is the last
  host.advance(1s);
  const auto published = host.published_statuses("base");
  CHECK(published.size() == 5);
  CHECK(published.back()["moving"] == false);
  CHECK(published.back()["halts"] == 1);
  CHECK(host.pending_tasks() == 0);

  REQUIRE(drive(host, -0.3, 0.3) == GateStatus::Ok);  // moving again: publishing starts again at once
  host.run_pending();
  CHECK(host.published_statuses("base").size() == 6);
}
