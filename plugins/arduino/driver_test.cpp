// The driver against the bridge firmware's emulator on a pseudo-terminal: the boot wait, drive, the heartbeat that
// keeps the firmware's 1 s watchdog fed while moving and silence while stopped, halt by its deadline on a hung port,
// the named fault when nothing answers, and the ultrasonic as obstacle zones.
#include <doctest/doctest.h>

#include <thread>

#include "arduino_driver.hpp"
#include "testing/arduino_emulator.hpp"
#include "testing/arduino_pty.hpp"

using namespace rcand::plugins::arduino;
using namespace std::chrono_literals;
using testing::ArduinoEmulator;
using testing::ArduinoPty;
using Board = ArduinoEmulator::Board;
using Lines = std::vector<ArduinoEmulator::Line>;

namespace {

ArduinoSettings arduino_test_settings(const std::string& port) {
  ArduinoSettings s;
  s.port = port;
  s.boot_timeout = 3000ms;
  s.command_timeout = 500ms;  // generous: the emulator is a thread of a test on a loaded machine
  s.reply_timeout = 500ms;
  return s;
}

std::unique_ptr<ArduinoDriver> arduino_started(const ArduinoSettings& settings) {
  auto driver = std::make_unique<ArduinoDriver>(settings, std::make_shared<ArduinoBus>(settings.port, settings.baud));
  driver->start();
  return driver;
}

std::size_t arduino_count_lines(const Lines& lines, const std::string& text) {
  std::size_t n = 0;
  for (const auto& line : lines) n += line.text == text;
  return n;
}

}  // namespace

TEST_CASE("arduino driver: waits out the board's reset on open, then drives with the firmware's PWM") {
  ArduinoPty pty;
  ArduinoEmulator emulator(pty.master(), 400ms);  // the bootloader: lines sent before the sketch runs are lost
  auto settings = arduino_test_settings(pty.slave_path());
  settings.max_pwm = 200;
  auto driver = arduino_started(settings);
  CHECK(emulator.board().boots == 1);
  CHECK(emulator.board().booting == false);
  CHECK(arduino_count_lines(emulator.received(), "{\"cmd\":\"ping\"}") >= 1);

  driver->set_wheel_speeds(0.5, -1.0);
  const Board board = emulator.board();
  CHECK(board.left == 100);
  CHECK(board.right == -200);
  driver->set_wheel_speeds(0.0, 0.0);
  CHECK_FALSE(emulator.board().moving());
  CHECK(driver->status()["commands"] == 2);
}

TEST_CASE("arduino driver: the heartbeat keeps the motors running past the firmware's 1 s; nothing is sent while stopped") {
  ArduinoPty pty;
  ArduinoEmulator emulator(pty.master());
  auto driver = arduino_started(arduino_test_settings(pty.slave_path()));
  driver->set_wheel_speeds(0.6, 0.6);
  emulator.clear_received();
  // 2.5 s with one command: without the heartbeat the firmware's watchdog stops the motors after 1 s.
  CHECK_FALSE(emulator.wait_until([](const Board& b, const Lines&) { return b.watchdog_stops > 0 || !b.moving(); }, 2500ms));
  CHECK(emulator.board().moving());
  const auto lines = emulator.received();
  CHECK(arduino_count_lines(lines, "{\"cmd\":\"drive\",\"left\":153,\"right\":153}") >= 5);
  for (std::size_t i = 1; i < lines.size(); ++i) CHECK(lines[i].at - lines[i - 1].at < 900ms);

  driver->set_wheel_speeds(0.0, 0.0);
  CHECK_FALSE(emulator.board().moving());
  emulator.clear_received();
  CHECK_FALSE(emulator.wait_until([](const Board&, const Lines& l) { return !l.empty(); }, 800ms));  // stopped: silence
  CHECK(emulator.board().watchdog_stops == 0);
}

TEST_CASE("arduino driver: halt returns by its deadline on a hung port, and the firmware's watchdog stops the motors") {
  ArduinoPty pty;
  ArduinoEmulator emulator(pty.master());
  auto settings = arduino_test_settings(pty.slave_path());
  settings.reply_timeout = 2000ms;  // a heartbeat waiting for a reply that never comes, while halt arrives
  settings.heartbeat = 100ms;
  auto driver = arduino_started(settings);
  driver->set_wheel_speeds(1.0, 1.0);
  REQUIRE(emulator.board().moving());
  emulator.set_hung(true);
  std::this_thread::sleep_for(300ms);  // the next heartbeat is written and waits for its ack
  const auto before = std::chrono::steady_clock::now();
  driver->halt();
  const auto took = std::chrono::steady_clock::now() - before;
  CHECK(took < 250ms);  // the deadline is 10 ms; the margin is for a loaded machine
  CHECK(driver->status()["left_pwm"] == 0);
  // The stop never reaches the hung board: its own watchdog stops the motors within 1 s of the last line.
  REQUIRE(emulator.wait_until([](const Board& b, const Lines&) { return b.watchdog_stops == 1; }, 3000ms));
  CHECK_FALSE(emulator.board().moving());
  // Unhung, the board reads what queued up (the heartbeat, then the stop): it stays stopped.
  emulator.set_hung(false);
  REQUIRE(emulator.wait_until([](const Board&, const Lines& l) { return !l.empty() && l.back().text == "{\"cmd\":\"stop\"}"; },
                              3000ms));
  CHECK_FALSE(emulator.board().moving());
}

TEST_CASE("arduino driver: after halt the motors are stopped and nothing more is sent") {
  ArduinoPty pty;
  ArduinoEmulator emulator(pty.master());
  auto driver = arduino_started(arduino_test_settings(pty.slave_path()));
  driver->set_wheel_speeds(1.0, 1.0);
  driver->halt();
  CHECK(emulator.wait_until([](const Board& b, const Lines&) { return !b.moving(); }, 2000ms));
  emulator.clear_received();
  CHECK_FALSE(emulator.wait_until([](const Board&, const Lines& l) { return !l.empty(); }, 600ms));
  CHECK(driver->status()["halts"] == 1);
  CHECK(driver->status()["halts_unconfirmed"] == 0);
}

TEST_CASE("arduino driver: a port where nothing answers is a named fault, and so is a missing port") {
  ArduinoPty pty;  // a tty, but no sketch behind it
  auto settings = arduino_test_settings(pty.slave_path());
  settings.boot_timeout = 600ms;
  ArduinoDriver driver(settings, std::make_shared<ArduinoBus>(settings.port, settings.baud));
  try {
    driver.start();
    FAIL("start() succeeded with nothing on the port");
  } catch (const rcand::sdk::DeviceFault& e) {
    CHECK(e.message() ==
          "no answer from the Arduino on " + pty.slave_path() + " at 115200 baud: is the bridge firmware flashed?");
    CHECK(e.device() == pty.slave_path());
    CHECK(e.hint().find("arduino_l298n_bridge.ino") != std::string::npos);
  }
  try {
    ArduinoBus bus("/dev/rcand-test-no-such-arduino", 115200);
    FAIL("opened a port that does not exist");
  } catch (const rcand::sdk::DeviceFault& e) {
    CHECK(e.message().starts_with("cannot open /dev/rcand-test-no-such-arduino: "));
    CHECK(e.hint().find("plugged in") != std::string::npos);
  }
}

TEST_CASE("arduino driver: the ultrasonic as obstacle zones; no echo, an unknown sensor and a hung port are not free space") {
  ArduinoPty pty;
  ArduinoEmulator emulator(pty.master());
  emulator.set_distance_mm(250);
  auto settings = arduino_test_settings(pty.slave_path());
  settings.ultrasonic = UltrasonicSettings{};
  settings.ultrasonic->poll_hz = 20;
  settings.ultrasonic->stale_after = 300ms;
  settings.reply_timeout = 100ms;
  auto driver = arduino_started(settings);
  const auto* zones = driver->ultrasonic();
  REQUIRE(zones != nullptr);
  auto wait_for = [&](const std::function<bool(const rcand::sdk::ObstacleReading&)>& predicate) {
    const auto until = std::chrono::steady_clock::now() + 3s;
    while (std::chrono::steady_clock::now() < until) {  // the driver offers no event: poll its reading
      if (predicate(zones->obstacles())) return true;
      emulator.wait_until([](const Board&, const Lines&) { return false; }, 10ms);
    }
    return false;
  };
  REQUIRE(wait_for([](const auto& r) { return r.available; }));
  auto reading = zones->obstacles();
  CHECK(reading.center_cm == doctest::Approx(25.0));
  CHECK(reading.nearest_cm == doctest::Approx(25.0));
  CHECK(reading.timestamp_ms > 0);

  emulator.set_distance_mm(-1);  // no echo
  CHECK(wait_for([](const auto& r) { return !r.available; }));
  emulator.set_distance_mm(1200);
  REQUIRE(wait_for([](const auto& r) { return r.available && r.nearest_cm > 100; }));
  emulator.set_hung(true);  // no more readings: stale
  CHECK(wait_for([](const auto& r) { return !r.available && r.timestamp_ms > 0; }));
  emulator.set_hung(false);
  CHECK(wait_for([](const auto& r) { return r.available; }));
  CHECK(driver->status()["ultrasonic"]["polls"].get<int>() > 3);

  ArduinoSettings no_echo_clear = settings;
  no_echo_clear.ultrasonic->no_echo_is_clear = true;
  UltrasonicZones clear_zones(std::make_shared<ArduinoState>(), *no_echo_clear.ultrasonic);
  CHECK_FALSE(clear_zones.obstacles().available);  // never read: unavailable whatever no_echo says
}

TEST_CASE("arduino driver: a sensor id the firmware does not know is a named fault at start") {
  ArduinoPty pty;
  ArduinoEmulator emulator(pty.master());
  auto settings = arduino_test_settings(pty.slave_path());
  settings.ultrasonic = UltrasonicSettings{};
  settings.ultrasonic->sensor_id = "vl53l0x";
  ArduinoDriver driver(settings, std::make_shared<ArduinoBus>(settings.port, settings.baud));
  try {
    driver.start();
    FAIL("start() took a sensor the firmware does not know");
  } catch (const rcand::sdk::DeviceFault& e) {
    CHECK(std::string(e.what()).find("does not know sensor 'vl53l0x': unknown sensor id") != std::string::npos);
  }
}
