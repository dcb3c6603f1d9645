// The Bus Watchdog end to end with a real process and a real pseudo-terminal: a child process runs the driver
// (wheels turning, joints on a slow move), the parent's emulator keeps seeing its polls for several watchdog
// periods without a trip, then the child is killed with SIGKILL and every emulated servo stops by itself.
#include <doctest/doctest.h>

#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstring>

#include "dynamixel_driver.hpp"
#include "posix_serial.hpp"
#include "testing/pty_pair.hpp"
#include "testing/servo_emulator.hpp"

using namespace rcand::plugins::dynamixel;
using namespace std::chrono_literals;
using nlohmann::json;
using testing::PtyPair;
using testing::ServoEmulator;
using Servos = std::map<std::uint8_t, ServoEmulator::Servo>;

namespace {

constexpr int kWatchdogMs = 100;

// A 50 ms reply timeout: the emulator answers at once, but 5 ms can be missed under ASan on a loaded machine.
json robot_config(const std::string& port) {
  json servos = json::array();
  for (int i = 1; i <= 4; ++i) servos.push_back({{"id", i}, {"joint", "j" + std::to_string(i)}});
  servos.push_back({{"id", 5}, {"wheel", "left"}});
  servos.push_back({{"id", 6}, {"wheel", "right"}, {"reverse", true}});
  return {{"port", port},   {"baud_rate", 1000000},   {"servos", servos},
          {"poll_hz", 100}, {"reply_timeout_ms", 50}, {"watchdog_ms", kWatchdogMs}};
}

// The child: waits for the emulator, drives, reports "R" (or "E" and why), then lives until it is killed.
[[noreturn]] void run_child(const std::string& port, int go, int ready) {
  char byte = 0;
  if (::read(go, &byte, 1) != 1) ::_exit(2);
  try {
    DynamixelDriver driver(DynamixelSettings::from(rcand::sdk::ConfigView(robot_config(port))),
                           std::make_shared<PosixSerial>(port, 1000000));
    driver.start();
    driver.set_wheel_speeds(0.5, 0.5);
    driver.set_joint_targets({{"j1", 120.0, 30.0}, {"j2", -120.0, 30.0}});
    (void)!::write(ready, "R", 1);
    for (;;) ::pause();
  } catch (const std::exception& e) {
    const std::string message = std::string("E") + e.what();
    (void)!::write(ready, message.data(), message.size());
  }
  ::_exit(1);
}

}  // namespace

TEST_CASE("bus watchdog: kill -9 the process running the driver and every servo stops by itself") {
  PtyPair pty;
  int go[2], ready[2];
  REQUIRE(::pipe(go) == 0);
  REQUIRE(::pipe(ready) == 0);
  // Fork before the emulator's thread exists: the child starts as a clean single-threaded process.
  const pid_t child = ::fork();
  REQUIRE(child >= 0);
  if (child == 0) run_child(pty.slave_path(), go[0], ready[1]);
  ::close(go[0]);
  ::close(ready[1]);

  ServoEmulator emulator(pty.master(), {1, 2, 3, 4, 5, 6});
  REQUIRE(::write(go[1], "G", 1) == 1);
  pollfd pfd{ready[0], POLLIN, 0};
  REQUIRE(::poll(&pfd, 1, 10'000) == 1);
  char reply[512] = {};
  const auto n = ::read(ready[0], reply, sizeof reply - 1);
  REQUIRE(n > 0);
  INFO("child: " << reply);
  REQUIRE(reply[0] == 'R');

  // Alive, the driver's polls keep the watchdog fed: five watchdog periods of polls (100 Hz) and no trip.
  emulator.clear_received();
  REQUIRE(emulator.wait_for_packets([](const auto& received) { return received.size() >= 50; }, 5s));
  for (std::uint8_t id = 1; id <= 6; ++id) CHECK(emulator.servo(id).watchdog_trips == 0);
  CHECK(emulator.servo(5).i32(kTableX.present_velocity) == 133);
  CHECK(emulator.servo(6).i32(kTableX.present_velocity) == -133);
  CHECK(emulator.servo(1).i32(kTableX.present_velocity) > 0);  // j1 still on its slow way to 120 deg

  REQUIRE(::kill(child, SIGKILL) == 0);
  const auto killed = std::chrono::steady_clock::now();
  int status = 0;
  REQUIRE(::waitpid(child, &status, 0) == child);
  CHECK(WIFSIGNALED(status));
  CHECK(WTERMSIG(status) == SIGKILL);

  REQUIRE(emulator.wait_until(
      [](const Servos& servos) {
        for (const auto& [id, s] : servos)
          if (s.watchdog_trips == 0 || s.i32(kTableX.present_velocity) != 0) return false;
        return true;
      },
      2s));
  for (std::uint8_t id = 1; id <= 6; ++id) {
    const auto s = emulator.servo(id);
    CAPTURE(id);
    CHECK(s.u8(kTableX.bus_watchdog) == 0xFF);  // -1: the watchdog fired
    CHECK(s.u8(kTableX.torque_enable) == 1);    // stopped, not dropped: an arm keeps holding
    CHECK(s.tripped_at - s.last_heard >= std::chrono::milliseconds(kWatchdogMs));
    // The last poll came at most one poll period (10 ms) before the kill; allow scheduling slack on top.
    CHECK(s.tripped_at - killed < std::chrono::milliseconds(kWatchdogMs + 100));
  }
  CHECK(emulator.servo(5).i32(kTableX.goal_velocity) == 0);
  const auto j1 = emulator.servo(1);
  CHECK(j1.i32(kTableX.present_position) < 2048 + 1365);  // stopped before 120 deg
  CHECK(j1.i32(kTableX.goal_position) == j1.i32(kTableX.present_position));
  ::close(go[1]);
  ::close(ready[0]);
}
