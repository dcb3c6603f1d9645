// The PCA9685 driver on the fake register-map bus: start-up sequence, one block write per update, halt in one
// transaction and on /OE, the named no-ACK fault, and halt's deadline on a wedged bus.
#include <doctest/doctest.h>

#include <rcand/sdk/testing/fake_host.hpp>

#include <chrono>
#include <fstream>
#include <thread>

#include "fake_pca9685_bus.hpp"
#include "pca9685_drive.hpp"

extern "C" const rcand_plugin_descriptor* RCAND_ENTRY_FUNCTION(void);

using namespace rcand::plugins::pca9685;
using namespace std::chrono_literals;
using nlohmann::json;
using testing::FakePca9685Bus;

namespace {

class FakePin final : public OutputPin {
 public:
  explicit FakePin(std::vector<bool>& levels) : levels_(levels) {}
  bool set(bool high) noexcept override {
    levels_.push_back(high);
    return true;
  }
  std::string describe() const override { return "fake line 4"; }

 private:
  std::vector<bool>& levels_;
};

json bridge_config() {
  return json::parse(R"({"address": 64, "port": 1, "pwm_frequency_hz": 1000,
                         "channels": {"left": {"pwm": 0, "in1": 1, "in2": 2}, "right": {"pwm": 5, "in1": 3, "in2": 4}}})");
}

Pca9685Settings settings_of(json config) { return Pca9685Settings::from(rcand::sdk::ConfigView(std::move(config))); }

struct Board {
  std::shared_ptr<FakePca9685Bus> bus = std::make_shared<FakePca9685Bus>();
  std::vector<bool> oe_levels;
  std::unique_ptr<Pca9685Drive> drive;
  explicit Board(json config = bridge_config(), bool with_oe = false) {
    auto oe = with_oe ? std::make_unique<FakePin>(oe_levels) : nullptr;
    drive = std::make_unique<Pca9685Drive>(settings_of(std::move(config)), bus, std::move(oe));
  }
  ~Board() { bus->release(); }
};

std::string error_of(const std::function<void()>& call) {
  try {
    call();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "no error";
}

}  // namespace

TEST_CASE("settings: address, port, frequency and /OE, with errors naming the key") {
  auto s = settings_of(bridge_config());
  CHECK(s.address == 0x40);
  CHECK(s.bus_path == "/dev/i2c-1");
  CHECK(s.prescale == 5);
  json c = bridge_config();
  c["address"] = "0x41";
  c["port"] = "/dev/i2c-3";
  c["oe_line"] = 4;
  s = settings_of(c);
  CHECK(s.address == 0x41);
  CHECK(s.bus_path == "/dev/i2c-3");
  CHECK(s.oe_chip == "/dev/gpiochip0");
  CHECK(s.oe_line == 4u);

  auto bad = [](const char* key, json value) {
    json c = bridge_config();
    c[key] = std::move(value);
    return error_of([&] { settings_of(c); });
  };
  CHECK(bad("address", 0x80).find("address: expected a 7-bit I2C address") == 0);
  CHECK(bad("address", "forty").find("address:") == 0);
  CHECK(bad("port", true).find("port: expected an I2C bus number") == 0);
  CHECK(bad("pwm_frequency_hz", 2000).find("pwm_frequency_hz: 2000") == 0);
  CHECK(bad("oscillator_hz", 1).find("oscillator_hz:") == 0);
  CHECK(bad("oe_chip", "/dev/gpiochip1").find("oe_line: required with oe_chip") == 0);
  CHECK(bad("halt_deadline_ms", 0).find("halt_deadline_ms:") == 0);
  CHECK(bad("channels", json::object()).find("channels.left: required") == 0);
}

TEST_CASE("settings: an ESC at a PWM frequency whose period is shorter than its pulses is refused (found by fuzzing)") {
  // At 1000 Hz (1017 Hz with its prescale) the period is 983 us: a 1500 us neutral would be a constant high.
  json c = json::parse(R"({"channels": {"left": {"esc": 0}, "right": {"esc": 1}}, "pwm_frequency_hz": 1000})");
  CHECK(error_of([&] { settings_of(c); }) ==
        "pwm_frequency_hz: 1000.0 Hz gives a period of 983 us, too short for the pulses of channels.left (up to max_us 2000.0 "
        "us): an ESC or servo needs 50..400 Hz (the default is 50)");
  c["pwm_frequency_hz"] = 400;  // 2500 us: the pulses fit
  CHECK(settings_of(c).prescale == 14);
  c["channels"]["left"] = {{"in1", 2}, {"in2", 3}};  // bridges have no pulse: any frequency the chip makes
  c["channels"]["right"] = {{"esc", 1}, {"max_us", 1900}};
  c["pwm_frequency_hz"] = 520;  // prescale 11: 1966 us
  CHECK_NOTHROW(settings_of(c));
  c["pwm_frequency_hz"] = 560;  // prescale 10: 1802 us
  CHECK(error_of([&] { settings_of(c); }).find("too short for the pulses of channels.right") != std::string::npos);
}

TEST_CASE("start: probe, the datasheet wake-up, PRE_SCALE verified, outputs stopped") {
  Board board;
  board.drive->start();
  const auto& bus = *board.bus;
  CHECK(bus.reg(reg::kPreScale) == 5);
  CHECK(bus.reg(reg::kMode1) == reg::kMode1Ai);  // awake, auto-increment, RESTART cleared itself
  CHECK(bus.reg(reg::kMode2) == reg::kMode2Outdrv);
  for (int ch = 0; ch < kChannels; ++ch) CHECK(bus.channel(ch) == ChannelCounts::full_off());
  const auto log = bus.transactions();
  REQUIRE(log.size() == 9);
  CHECK(log[0].read);  // the probe comes before any write
  CHECK(log[0].bytes == std::vector<std::uint8_t>{reg::kMode1});
  CHECK(log[1].bytes == std::vector<std::uint8_t>{0x00, 0x30});  // asleep first: PRE_SCALE is writable only then
  CHECK(log[4].bytes == std::vector<std::uint8_t>{0xFE, 5});
  CHECK(log[6].bytes == std::vector<std::uint8_t>{0x00, 0xA0});  // restart
  CHECK(log[7].read);                                            // PRE_SCALE read back
  CHECK(log[8].bytes.size() == 1 + 4 * kChannels);               // one block: every channel stopped
}

TEST_CASE("a missing board is a named fault, never a silent mock") {
  Board board;
  board.bus->set_present(false);
  CHECK(error_of([&] { board.drive->start(); }) == "no ACK at 0x40 on /dev/i2c-1: check power and address, try i2cdetect -y 1");
  CHECK(board.bus->transactions().size() == 1);  // nothing written after the failed probe
  CHECK_THROWS_AS(board.drive->set_wheel_speeds(0.5, 0.5), I2cError);

  json c = bridge_config();
  c["address"] = 0x41;
  Board wrong(c);
  CHECK(error_of([&] { wrong.drive->start(); }) == "no ACK at 0x41 on /dev/i2c-1: check power and address, try i2cdetect -y 1");

  // Through the plugin: a bus that does not exist fails the instance with the device named.
  rcand::sdk::testing::FakeHost host;
  std::ifstream in(RCAND_SOURCE_DIR "/manifests/pca9685.json");
  host.load(RCAND_ENTRY_FUNCTION, json::parse(in));
  json entry = bridge_config();
  entry["port"] = "/dev/i2c-77";
  CHECK_THROWS_WITH_AS(host.add_driver("wheels", "pca9685_i2c", entry), doctest::Contains("cannot open /dev/i2c-77"),
                       rcand::sdk::testing::HostError);
  CHECK(host.motion().actuators().empty());
}

TEST_CASE("every wheel update is one auto-increment block write") {
  Board board;
  board.drive->start();
  board.bus->clear_log();
  board.drive->set_wheel_speeds(0.5, -0.25);
  const auto log = board.bus->transactions();
  REQUIRE(log.size() == 1);
  CHECK(log[0].bytes[0] == reg::kLed0OnL);  // channels 0..5 in one go
  CHECK(log[0].bytes.size() == 1 + 4 * 6);
  const auto& bus = *board.bus;
  CHECK(bus.channel(0) == ChannelCounts::duty(0.5));
  CHECK(bus.channel(1) == ChannelCounts::full_on());
  CHECK(bus.channel(2) == ChannelCounts::full_off());
  CHECK(bus.channel(5) == ChannelCounts::duty(0.25));
  CHECK(bus.channel(3) == ChannelCounts::full_off());
  CHECK(bus.channel(4) == ChannelCounts::full_on());
  CHECK(board.drive->status()["left"] == 0.5);
}

TEST_CASE("halt: all outputs off in ONE transaction (ALL_LED), and /OE high before it") {
  Board board(bridge_config(), true);
  board.drive->start();
  CHECK(board.oe_levels == std::vector<bool>{false});  // enabled only once the chip is initialised
  board.drive->set_wheel_speeds(1.0, 1.0);
  board.bus->clear_log();
  board.drive->halt();
  const auto log = board.bus->transactions();
  REQUIRE(log.size() == 1);
  CHECK(log[0].bytes == all_off_block());
  for (int ch = 0; ch < kChannels; ++ch) CHECK(board.bus->channel(ch) == ChannelCounts::full_off());
  CHECK(board.oe_levels.back() == true);
  // The next command turns the outputs back on after writing them.
  board.drive->set_wheel_speeds(0.2, 0.2);
  CHECK(board.oe_levels.back() == false);
  CHECK(board.drive->status()["fail_safe"].get<std::string>().find("/OE (fake line 4) high") != std::string::npos);
}

TEST_CASE("halt with ESCs: one block write that puts every ESC at neutral") {
  Board board(json::parse(R"({"channels": {"left": {"esc": 0}, "right": {"esc": 1}}})"));
  board.drive->start();
  CHECK(board.bus->channel(0) == ChannelCounts::pulse(1500, 121, kInternalOscillatorHz));  // armed at neutral
  board.drive->set_wheel_speeds(1.0, -1.0);
  CHECK(board.bus->channel(0) == ChannelCounts::pulse(2000, 121, kInternalOscillatorHz));
  board.bus->clear_log();
  board.drive->halt();
  const auto log = board.bus->transactions();
  REQUIRE(log.size() == 1);
  CHECK(log[0].bytes.size() == 1 + 4 * kChannels);
  CHECK(board.bus->channel(0) == ChannelCounts::pulse(1500, 121, kInternalOscillatorHz));
  CHECK(board.bus->channel(1) == ChannelCounts::pulse(1500, 121, kInternalOscillatorHz));
  CHECK(board.drive->status()["fail_safe"].get<std::string>().find("NO /OE pin") != std::string::npos);
}

TEST_CASE("wedged bus: halt returns by its deadline on /OE, an update fails by its timeout, nothing stale lands after") {
  json c = bridge_config();
  c["halt_deadline_ms"] = 5;
  c["command_timeout_ms"] = 20;
  Board board(c, true);
  board.drive->start();
  board.drive->set_wheel_speeds(0.8, 0.8);
  board.bus->wedge();

  // Two updates on the wedged bus: the first is stuck in the transfer, the second queued behind it.
  std::string first_error, second_error;
  std::thread first([&] { first_error = error_of([&] { board.drive->set_wheel_speeds(0.3, 0.3); }); });
  std::this_thread::sleep_for(5ms);
  std::thread second([&] { second_error = error_of([&] { board.drive->set_wheel_speeds(-1.0, -1.0); }); });
  first.join();
  second.join();
  CHECK(first_error.find("no answer from 0x40 on /dev/i2c-1 within 20 ms") != std::string::npos);
  CHECK(second_error.find("within 20 ms") != std::string::npos);

  const auto started = std::chrono::steady_clock::now();
  board.drive->halt();
  const auto took = std::chrono::steady_clock::now() - started;
  CHECK(took < 5ms + 15ms);  // its deadline, plus scheduling slack on a loaded CI machine
  CHECK(board.oe_levels.back() == true);
  CHECK(board.drive->halts_unconfirmed() == 1);
  CHECK(board.drive->status()["last_error"].get<std::string>().find("outputs disabled by /OE") != std::string::npos);

  // The bus recovers: the stuck transfer finishes, then the halt; the queued -1.0 update never reaches the chip.
  board.bus->clear_log();
  board.bus->release();
  std::this_thread::sleep_for(50ms);
  for (int ch = 0; ch < kChannels; ++ch) CHECK(board.bus->channel(ch) == ChannelCounts::full_off());
  CHECK(board.oe_levels.back() == true);
  const auto log = board.bus->transactions();
  REQUIRE(log.size() == 2);
  CHECK(log[0].bytes[0] == reg::kLed0OnL);  // the 0.3 update that was already on the wire
  CHECK(log[1].bytes == all_off_block());   // then the halt; the queued -1.0 update was dropped
}

TEST_CASE("through the motion gate: the e-stop halts the board in one transaction") {
  rcand::sdk::testing::FakeHost host;
  auto bus = std::make_shared<FakePca9685Bus>();
  auto& drive = host.add_driver_instance<Pca9685Drive>("wheels", settings_of(bridge_config()), bus, nullptr);
  REQUIRE(host.motion().actuate_as<rcand::sdk::DifferentialDrive>("wheels", [](auto& d) { d.set_wheel_speeds(1, 1); }) ==
          rcand::sdk::GateStatus::Ok);
  bus->clear_log();
  host.latch_estop("test");
  REQUIRE(bus->transactions().size() == 1);
  CHECK(bus->transactions()[0].bytes == all_off_block());
  CHECK(host.motion().actuate_as<rcand::sdk::DifferentialDrive>("wheels", [](auto& d) { d.set_wheel_speeds(1, 1); }) ==
        rcand::sdk::GateStatus::EstopActive);
  CHECK(bus->transactions().size() == 1);
  CHECK(drive.status()["halts"] == 1);
}

TEST_CASE("halt on the fake bus stays far below 2 ms") {
  Board board;
  board.drive->start();
  constexpr int kRuns = 200;
  const auto started = std::chrono::steady_clock::now();
  for (int i = 0; i < kRuns; ++i) board.drive->halt();
  const auto mean = (std::chrono::steady_clock::now() - started) / kRuns;
  MESSAGE("mean halt on the fake bus: ", std::chrono::duration<double, std::micro>(mean).count(), " us");
  CHECK(mean < 2ms);
  CHECK(board.drive->halts_unconfirmed() == 0);
}
