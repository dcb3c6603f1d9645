// End to end with the real kernel, configured like the reference runtime's arduino_l298n preset: an rcand process
// drives the bridge firmware's emulator through teleop (POST /api/action move -> motion gate -> one JSON line), the
// ultrasonic's reading stops a forward move (the obstacle rule nav and teleop share), and after kill -9 the
// firmware's own 1 s watchdog stops the motors.
#include <doctest/doctest.h>

#include <rcand_process.hpp>

#include <algorithm>

#include "testing/arduino_emulator.hpp"
#include "testing/arduino_pty.hpp"

using namespace std::chrono_literals;
using nlohmann::json;
using rcand::plugins::arduino::testing::ArduinoEmulator;
using rcand::plugins::arduino::testing::ArduinoPty;
using ArduinoBoard = ArduinoEmulator::Board;
using ArduinoLines = std::vector<ArduinoEmulator::Line>;

TEST_CASE("rcand with an Arduino bridge: teleop moves it, the ultrasonic stops it, kill -9 and the firmware stops it") {
  ArduinoPty pty;
  ArduinoEmulator emulator(pty.master(), 300ms);  // the board resets when rcand opens the port
  emulator.set_distance_mm(1500);
  json config = rcand::test::sim_config();
  config["drivers"] =
      json::array({{{"id", "motor_driver"},
                    {"protocol", "arduino_serial_json"},
                    {"port", pty.slave_path()},
                    {"baud", 115200},
                    {"channels",
                     {{"left_pwm_pin", 5},
                      {"left_dir_a", 6},
                      {"left_dir_b", 7},
                      {"right_pwm_pin", 10},
                      {"right_dir_a", 8},
                      {"right_dir_b", 9}}},
                    {"max_pwm", 255},
                    {"deadband_pwm", 40},
                    {"ultrasonic", {{"sensor_type", "hcsr04"}, {"trigger_pin", 12}, {"echo_pin", 11}, {"poll_hz", 20}}}}});
  config["rcan_protocol"]["capabilities"] = {"status", "teleop"};
  config["agent"] = {{"min_obstacle_m", 0.3}};
  rcand::test::RcandProcess rcand(config);
  const std::string log_hint = rcand.stderr_text();
  INFO(log_hint);

  // A forward move in the clear: the motors run, and keep running past the firmware's 1 s on the heartbeat.
  int status = 0;
  auto answer =
      rcand.json("POST", "/api/action", "user-token", R"({"type":"move","linear":0.5,"angular":0,"duration_ms":20000})", &status);
  const std::string answer_text = answer.dump();
  INFO(answer_text);
  REQUIRE(status == 200);
  REQUIRE(emulator.wait_until([](const ArduinoBoard& b, const ArduinoLines&) { return b.left > 0 && b.right > 0; }, 5s));
  CHECK_FALSE(emulator.wait_until([](const ArduinoBoard& b, const ArduinoLines&) { return !b.moving(); }, 1500ms));

  // Something 15 cm ahead: teleop's obstacle check latches the e-stop and the halt stops the motors.
  emulator.set_distance_mm(150);
  REQUIRE(emulator.wait_until([](const ArduinoBoard& b, const ArduinoLines&) { return !b.moving(); }, 3s));
  CHECK(emulator.board().watchdog_stops == 0);  // stopped by rcand's stop, not by the firmware's watchdog
  const auto estop = rcand.json("GET", "/api/estop", "guest-token");
  const std::string estop_text = estop.dump();
  INFO(estop_text);
  CHECK(estop["estopped"] == true);
  CHECK(estop_text.find("obstacle at 15.0 cm") != std::string::npos);

  // Cleared, but the obstacle is still there: a forward move is refused before it runs.
  REQUIRE(rcand.json("POST", "/api/estop/clear", "owner-token", "", &status)["status"] == "cleared");
  rcand.json("POST", "/api/action", "user-token", R"({"type":"move","linear":0.5,"angular":0,"duration_ms":20000})", &status);
  CHECK(status != 200);
  CHECK_FALSE(emulator.board().moving());

  // Clear again and in the clear: it moves; then rcand dies and the firmware's watchdog stops the motors.
  emulator.set_distance_mm(1500);
  emulator.clear_received();
  // Two polls read: the first one's reply is in the driver (it polls one at a time).
  REQUIRE(emulator.wait_until(
      [](const ArduinoBoard&, const ArduinoLines& lines) {
        return std::count_if(lines.begin(), lines.end(),
                             [](const auto& l) { return l.text.find("\"sensor\"") != std::string::npos; }) >= 2;
      },
      3s));
  rcand.json("POST", "/api/estop/clear", "owner-token", "", &status);
  answer =
      rcand.json("POST", "/api/action", "user-token", R"({"type":"move","linear":0.5,"angular":0,"duration_ms":20000})", &status);
  REQUIRE(status == 200);
  REQUIRE(emulator.wait_until([](const ArduinoBoard& b, const ArduinoLines&) { return b.moving(); }, 5s));
  rcand.kill_hard();
  const auto killed = std::chrono::steady_clock::now();
  REQUIRE(emulator.wait_until([](const ArduinoBoard& b, const ArduinoLines&) { return b.watchdog_stops == 1; }, 3s));
  const auto board = emulator.board();
  CHECK_FALSE(board.moving());
  CHECK(board.watchdog_stopped_at - killed < 1500ms);  // 1 s of silence, plus the last heartbeat's age
}
