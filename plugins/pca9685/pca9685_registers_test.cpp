// The PCA9685 arithmetic against its datasheet, and the motor wiring rules (shoot-through never happens).
#include <doctest/doctest.h>

#include <rcand/sdk/config_view.hpp>

#include <random>

#include "motor_channels.hpp"
#include "pca9685_registers.hpp"

using namespace rcand::plugins::pca9685;
using nlohmann::json;

TEST_CASE("prescale: the datasheet formula and its vectors") {
  // Datasheet 7.3.5: the default PRE_SCALE 1Eh is 200 Hz; 03h is the fastest (1526 Hz), FFh the slowest (24 Hz).
  CHECK(prescale_for(200.0) == 0x1E);
  CHECK(prescale_for(1526.0) == 0x03);
  CHECK(prescale_for(frequency_of(0xFF)) == 0xFF);
  CHECK(frequency_of(0x03) == doctest::Approx(1525.88).epsilon(1e-4));
  CHECK(frequency_of(0xFF) == doctest::Approx(23.84).epsilon(1e-3));
  // The usual settings: 50 Hz servos and ESCs, 60 Hz (Adafruit's examples), 1 kHz motors.
  CHECK(prescale_for(50.0) == 121);
  CHECK(prescale_for(60.0) == 101);
  CHECK(prescale_for(1000.0) == 5);
  // A calibrated or external oscillator moves the value: 27 MHz at 50 Hz.
  CHECK(prescale_for(50.0, 27'000'000.0) == 131);
  // Outside the chip's range, or nonsense: no value at all, never a clamp.
  CHECK_FALSE(prescale_for(2000.0).has_value());
  CHECK_FALSE(prescale_for(20.0).has_value());
  CHECK_FALSE(prescale_for(0.0).has_value());
  CHECK_FALSE(prescale_for(-50.0).has_value());
  CHECK_FALSE(prescale_for(std::nan("")).has_value());
}

TEST_CASE("channel counts: full off, full on, duty and pulses") {
  CHECK(ChannelCounts::duty(0.0) == ChannelCounts{0, 0x1000});
  CHECK(ChannelCounts::duty(-0.5) == ChannelCounts::full_off());
  CHECK(ChannelCounts::duty(std::nan("")) == ChannelCounts::full_off());
  CHECK(ChannelCounts::duty(1.0) == ChannelCounts{0x1000, 0});
  CHECK(ChannelCounts::duty(0.5) == ChannelCounts{0, 2048});
  CHECK(ChannelCounts::duty(1e-6) == ChannelCounts{0, 1});  // on, however little
  CHECK(ChannelCounts::duty(0.99999) == ChannelCounts{0, 4095});
  // 1.5 ms at 50 Hz (prescale 121): 1500 us * 25 MHz / 122 = 307.4 counts.
  CHECK(ChannelCounts::pulse(1500.0, 121, kInternalOscillatorHz) == ChannelCounts{0, 307});
  CHECK(ChannelCounts::pulse(1000.0, 121, kInternalOscillatorHz) == ChannelCounts{0, 205});
}

TEST_CASE("blocks: one auto-increment write per channel range, ALL_LED for everything off") {
  ChannelTable table{};
  table[2] = ChannelCounts::duty(0.5);
  table[3] = ChannelCounts::full_on();
  CHECK(channel_block(table, 2, 3) == std::vector<std::uint8_t>{0x0E, 0x00, 0x00, 0x00, 0x08, 0x00, 0x10, 0x00, 0x00});
  CHECK(all_off_block() == std::vector<std::uint8_t>{0xFA, 0x00, 0x00, 0x00, 0x10});
  const auto wake = wake_sequence(121);
  REQUIRE(wake.size() == 5);
  CHECK(wake[0] == std::vector<std::uint8_t>{0x00, 0x30});  // asleep, auto-increment on, RESTART written 0
  CHECK(wake[1] == all_off_block());
  CHECK(wake[2] == std::vector<std::uint8_t>{0x01, 0x04});  // totem pole
  CHECK(wake[3] == std::vector<std::uint8_t>{0xFE, 121});
  CHECK(wake[4] == std::vector<std::uint8_t>{0x00, 0x20});  // awake
  CHECK(restart_block() == std::vector<std::uint8_t>{0x00, 0xA0});
}

TEST_CASE("motor layout: parsed with errors naming the key") {
  auto error_of = [](const char* text) {
    try {
      parse_motor_layout(json::parse(text));
    } catch (const rcand::sdk::ConfigError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  CHECK(error_of(R"({"left": {"in1": 0, "in2": 1}})").find("channels.right: required") == 0);
  CHECK(error_of(R"({"left": {"in1": 0}, "right": {"in1": 2, "in2": 3}})").find("channels.left.in2: required") == 0);
  CHECK(error_of(R"({"left": {"in1": 0, "in2": 16}, "right": {"esc": 2}})") ==
        "channels.left.in2: expected a channel number 0..15, found 16");
  CHECK(error_of(R"({"left": {"in1": 0, "in2": 1}, "right": {"in1": 1, "in2": 3}})") ==
        "channels.right: channel 1 is used twice");
  CHECK(error_of(R"({"left": {"in1": 0, "in2": 1, "speed": 2}, "right": {"esc": 2}})").find("channels.left.speed: unknown key") ==
        0);
  CHECK(error_of(R"({"left": {"esc": 0, "in1": 1}, "right": {"esc": 2}})").find("an esc motor has one channel") !=
        std::string::npos);
  CHECK(error_of(R"({"left": {"esc": 0, "min_us": 1600}, "right": {"esc": 2}})").find("min_us < neutral_us") !=
        std::string::npos);
  CHECK(error_of(R"({"left": {"esc": 0}, "right": {"esc": 2}, "pan": {"esc": 3}})") ==
        "channels.pan: unknown motor (known: left, right)");
  CHECK(error_of("null").find("channels: required") == 0);
  const auto layout =
      parse_motor_layout(json::parse(R"({"left": {"pwm": 0, "in1": 1, "in2": 2}, "right": {"pwm": 5, "in1": 3, "in2": 4}})"));
  CHECK(layout.span() == std::pair{0, 5});
  CHECK(layout.left.kind == Motor::Kind::BridgeWithPwm);
}

TEST_CASE("motor outputs: direction and speed per wiring, ESC pulses, reverse") {
  ChannelTable t{};
  const auto layout = parse_motor_layout(
      json::parse(R"({"left": {"pwm": 0, "in1": 1, "in2": 2}, "right": {"in1": 3, "in2": 4, "reverse": true}})"));
  layout.left.apply(0.5, t, 121, kInternalOscillatorHz);
  CHECK(t[0] == ChannelCounts::duty(0.5));
  CHECK(t[1] == ChannelCounts::full_on());
  CHECK(t[2] == ChannelCounts::full_off());
  layout.left.apply(-1.0, t, 121, kInternalOscillatorHz);
  CHECK(t[0] == ChannelCounts::full_on());
  CHECK(t[1] == ChannelCounts::full_off());
  CHECK(t[2] == ChannelCounts::full_on());
  layout.right.apply(0.25, t, 121, kInternalOscillatorHz);  // reversed: forward is in2
  CHECK(t[3] == ChannelCounts::full_off());
  CHECK(t[4] == ChannelCounts::duty(0.25));

  const auto esc =
      parse_motor_layout(json::parse(R"({"left": {"esc": 8}, "right": {"esc": 9, "min_us": 1100, "max_us": 1900}})"));
  esc.left.apply(0.0, t, 121, kInternalOscillatorHz);
  CHECK(t[8] == ChannelCounts::pulse(1500, 121, kInternalOscillatorHz));
  esc.left.apply(1.0, t, 121, kInternalOscillatorHz);
  CHECK(t[8] == ChannelCounts::pulse(2000, 121, kInternalOscillatorHz));
  esc.right.apply(-1.0, t, 121, kInternalOscillatorHz);
  CHECK(t[9] == ChannelCounts::pulse(1100, 121, kInternalOscillatorHz));
  esc.right.apply(5.0, t, 121, kInternalOscillatorHz);  // clamped
  CHECK(t[9] == ChannelCounts::pulse(1900, 121, kInternalOscillatorHz));
}

TEST_CASE("shoot-through: random command sequences never leave both inputs of a bridge on") {
  const auto layout =
      parse_motor_layout(json::parse(R"({"left": {"pwm": 0, "in1": 1, "in2": 2}, "right": {"in1": 3, "in2": 4}})"));
  std::mt19937 random(17);
  std::uniform_real_distribution<double> speed(-1.5, 1.5);
  ChannelTable t{};
  t.fill(ChannelCounts::full_off());  // as the driver starts: every channel off
  auto on = [&](int ch) { return !(t[static_cast<std::size_t>(ch)] == ChannelCounts::full_off()); };
  for (int i = 0; i < 100'000; ++i) {
    const double s = i % 97 == 0 ? std::nan("") : i % 13 == 0 ? 0.0 : speed(random);
    (i % 2 ? layout.left : layout.right).apply(s, t, 121, kInternalOscillatorHz);
    REQUIRE_FALSE((on(1) && on(2)));
    REQUIRE_FALSE((on(3) && on(4)));
  }
}
