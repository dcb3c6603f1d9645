// End to end with the real kernel: an rcand process drives an SO-ARM101-like arm (six emulated STS3215 servos on a
// pseudo-terminal) through the arm capability (POST /api/action arm_pose -> motion gate -> one sync write), the
// e-stop holds the arm with the torque on, a servo that stops answering shows as a named fault in /api/status, and
// after kill -9 the servos do exactly what the manifest's fail_safe says: keep their last goal (no bus watchdog).
#include <doctest/doctest.h>

#include <rcand_process.hpp>

#include "dynamixel/testing/pty_pair.hpp"
#include "sts_table.hpp"
#include "testing/sts_emulator.hpp"

using namespace rcand::plugins::feetech;
using namespace std::chrono_literals;
using nlohmann::json;
using rcand::plugins::dynamixel::testing::PtyPair;
using testing::StsEmulator;
using StsServos = std::map<std::uint8_t, StsEmulator::Servo>;

TEST_CASE("rcand with a feetech SO-ARM101: arm_pose moves a servo, the e-stop holds the arm, a lost servo is named") {
  PtyPair pty;
  StsEmulator emulator(pty.master(), {1, 2, 3, 4, 5, 6});
  const std::vector<std::string> joints{"shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll", "gripper"};
  json config = rcand::test::sim_config();
  json servos = json::array(), kinematics = json::array();
  for (int i = 1; i <= 6; ++i) {
    servos.push_back({{"id", i}, {"joint", joints[static_cast<std::size_t>(i - 1)]}});
    kinematics.push_back({{"joint", joints[static_cast<std::size_t>(i - 1)]}, {"min_deg", -90}, {"max_deg", 90}});
  }
  config["physics"]["kinematics"] = kinematics;
  config["drivers"] = json::array({{{"id", "arm0"},
                                    {"protocol", "feetech"},
                                    {"port", pty.slave_path()},
                                    {"model", "STS3215"},
                                    {"servos", servos},
                                    {"poll_hz", 100},
                                    {"reply_timeout_ms", 20}}});
  config["rcan_protocol"]["capabilities"] = {"status", "arm"};
  rcand::test::RcandProcess rcand(config);

  int status = 0;
  auto answer = rcand.json("POST", "/api/action", "owner-token", R"({"type":"arm_pose","joints":{"shoulder_pan":30}})", &status);
  INFO(answer.dump(), "\n", rcand.stderr_text());
  REQUIRE(status == 200);
  CHECK(emulator.wait_until([](const StsServos& s) { return s.at(1).signed16(sts::kPresentPosition) == 2048 + 341; }, 5s));
  for (std::uint8_t id = 1; id <= 6; ++id) CHECK(emulator.servo(id).u8(sts::kTorqueEnable) == 1);

  // A slow move, then the e-stop: one sync write holds every joint where it is, torque on.
  answer = rcand.json("POST", "/api/action", "owner-token",
                      R"({"type":"arm_pose","joints":{"shoulder_pan":-10},"velocity_dps":10})", &status);
  REQUIRE(status == 200);
  REQUIRE(emulator.wait_until([](const StsServos& s) { return s.at(1).signed16(sts::kPresentPosition) < 2048 + 300; }, 5s));
  REQUIRE(rcand.request("POST", "/api/stop", "owner-token").status == 200);
  REQUIRE(emulator.wait_until([](const StsServos& s) { return s.at(1).signed16(sts::kPresentSpeed) == 0; }, 2s));
  const auto held = emulator.servo(1);
  CHECK(held.u8(sts::kTorqueEnable) == 1);
  CHECK(held.signed16(sts::kGoalPosition) > 2048);  // stopped on the way: nowhere near -10 deg (2048 - 114)
  CHECK(held.signed16(sts::kGoalPosition) == held.signed16(sts::kPresentPosition));

  // A servo that stops answering: the driver's status names it, and so does the robot's.
  emulator.set_present(5, false);
  json drivers;
  for (int i = 0; i < 100; ++i) {
    drivers = rcand.json("GET", "/api/drivers/arm0", "owner-token", "", &status)["status"];
    if (drivers.contains("fault")) break;
    emulator.wait_for_packets([](const auto& received) { return received.size() > 50; }, 100ms);  // some polls go by
    emulator.clear_received();
  }
  INFO(drivers.dump());
  REQUIRE(drivers.contains("fault"));
  CHECK(drivers["fault"].get<std::string>().find("Feetech servo ID 5 (wrist_roll) on " + pty.slave_path() + " lost") == 0);

  // No bus watchdog on STS servos: after kill -9 a joint keeps the goal it last had (the manifest says so).
  emulator.set_present(5, true);
  const auto goal = emulator.servo(1).signed16(sts::kGoalPosition);
  rcand.kill_hard();
  CHECK(emulator.servo(1).u8(sts::kTorqueEnable) == 1);
  CHECK(emulator.servo(1).signed16(sts::kGoalPosition) == goal);
}
