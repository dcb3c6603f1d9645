// End to end with the real kernel: an rcand process drives six emulated servos on a pseudo-terminal through the
// arm capability (POST /api/action arm_pose -> motion gate -> one sync write), then dies by SIGKILL, and the
// servos' Bus Watchdog stops every one of them by itself, torque kept on.
#include <doctest/doctest.h>

#include <rcand_process.hpp>

#include "models.hpp"
#include "testing/pty_pair.hpp"
#include "testing/servo_emulator.hpp"

using namespace rcand::plugins::dynamixel;
using namespace std::chrono_literals;
using nlohmann::json;
using testing::PtyPair;
using testing::ServoEmulator;
using Servos = std::map<std::uint8_t, ServoEmulator::Servo>;

TEST_CASE("rcand with a dynamixel arm: arm_pose moves a servo; kill -9 and the watchdog stops them all") {
  PtyPair pty;
  ServoEmulator emulator(pty.master(), {1, 2, 3, 4, 5, 6});
  json config = rcand::test::sim_config();
  json servos = json::array(), kinematics = json::array();
  for (int i = 1; i <= 6; ++i) {
    servos.push_back({{"id", i}, {"joint", "j" + std::to_string(i)}});
    kinematics.push_back({{"joint", "j" + std::to_string(i)}, {"min_deg", -90}, {"max_deg", 90}});
  }
  config["physics"]["kinematics"] = kinematics;
  // A 50 ms reply timeout: the emulator answers at once, but a 5 ms one was missed under ASan on a loaded machine.
  config["drivers"] = json::array({{{"id", "arm0"},
                                    {"protocol", "dynamixel"},
                                    {"port", pty.slave_path()},
                                    {"baud_rate", 1000000},
                                    {"servos", servos},
                                    {"poll_hz", 100},
                                    {"reply_timeout_ms", 50},
                                    {"watchdog_ms", 100}}});
  config["rcan_protocol"]["capabilities"] = {"status", "arm"};
  rcand::test::RcandProcess rcand(config);

  int status = 0;
  const auto answer = rcand.json("POST", "/api/action", "owner-token", R"({"type":"arm_pose","joints":{"j1":30}})", &status);
  INFO(answer.dump(), "\n", rcand.stderr_text());
  REQUIRE(status == 200);
  CHECK(emulator.wait_until([](const Servos& s) { return s.at(1).i32(kTableX.goal_position) == 2048 + 341; }, 5s));
  for (std::uint8_t id = 1; id <= 6; ++id) CHECK(emulator.servo(id).u8(kTableX.bus_watchdog) == 5);

  emulator.clear_received();
  REQUIRE(emulator.wait_for_packets([](const auto& received) { return received.size() >= 30; }, 5s));  // polls flow
  for (std::uint8_t id = 1; id <= 6; ++id) CHECK(emulator.servo(id).watchdog_trips == 0);

  rcand.kill_hard();
  const auto killed = std::chrono::steady_clock::now();
  REQUIRE(emulator.wait_until(
      [](const Servos& s) {
        for (const auto& [id, servo] : s)
          if (servo.watchdog_trips == 0) return false;
        return true;
      },
      2s));
  for (std::uint8_t id = 1; id <= 6; ++id) {
    const auto s = emulator.servo(id);
    CAPTURE(id);
    CHECK(s.u8(kTableX.bus_watchdog) == 0xFF);
    CHECK(s.u8(kTableX.torque_enable) == 1);
    CHECK(s.tripped_at - killed < 250ms);
  }
}
