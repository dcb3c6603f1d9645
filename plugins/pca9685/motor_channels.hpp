// How a motor is wired to PCA9685 channels, from the driver's `channels` block:
//   {pwm: 0, in1: 1, in2: 2}   an H-bridge with a speed input (TB6612, L298N with EN): inputs full on/off, duty on pwm
//   {in1: 0, in2: 1}           an H-bridge driven by its inputs alone (DRV8833, MX1508): duty on the forward input
//   {esc: 0}                   an RC ESC or continuous servo: a pulse of min_us..neutral_us..max_us
// plus `reverse: true` for a motor mounted backwards. The two inputs of a bridge are never both on.
#pragma once

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

#include "pca9685_registers.hpp"

namespace rcand::plugins::pca9685 {

struct Motor {
  enum class Kind { Bridge, BridgeWithPwm, Esc };
  Kind kind = Kind::Bridge;
  int pwm = -1, in1 = -1, in2 = -1, esc = -1;
  double min_us = 1000.0, neutral_us = 1500.0, max_us = 2000.0;
  bool reverse = false;

  std::vector<int> channels() const;
  // This motor's channels for `speed` in [-1, 1] (clamped; NaN is 0) into `table`.
  void apply(double speed, ChannelTable& table, int prescale, double oscillator_hz) const;
  // Stopped: a bridge's channels full off (coast), an ESC's neutral pulse.
  void stop(ChannelTable& table, int prescale, double oscillator_hz) const { apply(0.0, table, prescale, oscillator_hz); }
};

struct MotorLayout {
  Motor left;
  Motor right;
  bool any_esc() const { return left.kind == Motor::Kind::Esc || right.kind == Motor::Kind::Esc; }
  // The lowest and highest channel a wheel update touches: one block write covers them.
  std::pair<int, int> span() const;
};

// Parses `channels` ({left: {...}, right: {...}}). Throws sdk::ConfigError naming the key ("channels.left.in2: ...")
// on a missing or out-of-range channel, a channel used twice, or an unknown key.
MotorLayout parse_motor_layout(const nlohmann::json& channels);

}  // namespace rcand::plugins::pca9685
