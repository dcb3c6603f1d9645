#include "motor_channels.hpp"

#include <rcand/sdk/config_view.hpp>

#include <algorithm>
#include <cmath>
#include <set>

namespace rcand::plugins::pca9685 {

namespace {

using nlohmann::json;

int channel_at(const json& motor, const char* key, const std::string& at) {
  const auto it = motor.find(key);
  if (it == motor.end()) return -1;
  if (!it->is_number_integer() || it->get<long long>() < 0 || it->get<long long>() >= kChannels)
    throw sdk::ConfigError(at + "." + key + ": expected a channel number 0..15, found " + it->dump());
  return static_cast<int>(it->get<long long>());
}

double pulse_at(const json& motor, const char* key, const std::string& at, double fallback) {
  const auto it = motor.find(key);
  if (it == motor.end()) return fallback;
  if (!it->is_number() || !std::isfinite(it->get<double>()) || it->get<double>() < 500.0 || it->get<double>() > 2500.0)
    throw sdk::ConfigError(at + "." + key + ": expected a pulse width in microseconds, 500..2500, found " + it->dump());
  return it->get<double>();
}

Motor parse_motor(const json& channels, const char* side) {
  const std::string at = std::string("channels.") + side;
  const auto it = channels.find(side);
  if (it == channels.end())
    throw sdk::ConfigError(at + ": required: the " + std::string(side) +
                           " motor's channels ({pwm, in1, in2}, {in1, in2} or {esc})");
  const json& m = *it;
  if (!m.is_object()) throw sdk::ConfigError(at + ": expected a map of channels, found " + m.dump());
  static const std::set<std::string> kKeys{"pwm", "in1", "in2", "esc", "min_us", "neutral_us", "max_us", "reverse"};
  for (const auto& [key, value] : m.items())
    if (!kKeys.count(key))
      throw sdk::ConfigError(at + "." + key + ": unknown key (known: pwm, in1, in2, esc, min_us, neutral_us, max_us, reverse)");

  Motor motor;
  motor.pwm = channel_at(m, "pwm", at);
  motor.in1 = channel_at(m, "in1", at);
  motor.in2 = channel_at(m, "in2", at);
  motor.esc = channel_at(m, "esc", at);
  if (const auto r = m.find("reverse"); r != m.end()) {
    if (!r->is_boolean()) throw sdk::ConfigError(at + ".reverse: expected true or false, found " + r->dump());
    motor.reverse = r->get<bool>();
  }
  if (motor.esc >= 0) {
    if (motor.pwm >= 0 || motor.in1 >= 0 || motor.in2 >= 0)
      throw sdk::ConfigError(at + ": an esc motor has one channel; remove pwm, in1 and in2");
    motor.kind = Motor::Kind::Esc;
    motor.min_us = pulse_at(m, "min_us", at, motor.min_us);
    motor.neutral_us = pulse_at(m, "neutral_us", at, motor.neutral_us);
    motor.max_us = pulse_at(m, "max_us", at, motor.max_us);
    if (!(motor.min_us < motor.neutral_us && motor.neutral_us < motor.max_us))
      throw sdk::ConfigError(at + ": needs min_us < neutral_us < max_us");
    return motor;
  }
  if (motor.in1 < 0) throw sdk::ConfigError(at + ".in1: required for an H-bridge motor (or give esc)");
  if (motor.in2 < 0) throw sdk::ConfigError(at + ".in2: required for an H-bridge motor (or give esc)");
  motor.kind = motor.pwm >= 0 ? Motor::Kind::BridgeWithPwm : Motor::Kind::Bridge;
  return motor;
}

}  // namespace

std::vector<int> Motor::channels() const {
  std::vector<int> out;
  for (int ch : {pwm, in1, in2, esc})
    if (ch >= 0) out.push_back(ch);
  return out;
}

void Motor::apply(double speed, ChannelTable& table, int prescale, double oscillator_hz) const {
  double s = std::isfinite(speed) ? std::clamp(speed, -1.0, 1.0) : 0.0;
  if (reverse) s = -s;
  auto at = [&](int ch) -> ChannelCounts& { return table[static_cast<std::size_t>(ch)]; };
  switch (kind) {
    case Kind::Esc:
      at(esc) = ChannelCounts::pulse(s >= 0 ? neutral_us + s * (max_us - neutral_us) : neutral_us + s * (neutral_us - min_us),
                                     prescale, oscillator_hz);
      return;
    case Kind::BridgeWithPwm:
      // Direction on the inputs, speed on pwm. At 0 both inputs are off: coast, never both on.
      at(in1) = s > 0 ? ChannelCounts::full_on() : ChannelCounts::full_off();
      at(in2) = s < 0 ? ChannelCounts::full_on() : ChannelCounts::full_off();
      at(pwm) = ChannelCounts::duty(std::abs(s));
      return;
    case Kind::Bridge:
      at(in1) = s > 0 ? ChannelCounts::duty(s) : ChannelCounts::full_off();
      at(in2) = s < 0 ? ChannelCounts::duty(-s) : ChannelCounts::full_off();
      return;
  }
}

std::pair<int, int> MotorLayout::span() const {
  std::vector<int> all = left.channels();
  for (int ch : right.channels()) all.push_back(ch);
  return {*std::min_element(all.begin(), all.end()), *std::max_element(all.begin(), all.end())};
}

MotorLayout parse_motor_layout(const json& channels) {
  if (!channels.is_object())
    throw sdk::ConfigError("channels: required: {left: {...}, right: {...}} naming each motor's PCA9685 channels");
  for (const auto& [key, value] : channels.items())
    if (key != "left" && key != "right") throw sdk::ConfigError("channels." + key + ": unknown motor (known: left, right)");
  MotorLayout layout{parse_motor(channels, "left"), parse_motor(channels, "right")};
  std::set<int> used;
  for (const auto& [side, motor] : {std::pair{"left", &layout.left}, std::pair{"right", &layout.right}})
    for (int ch : motor->channels())
      if (!used.insert(ch).second)
        throw sdk::ConfigError(std::string("channels.") + side + ": channel " + std::to_string(ch) + " is used twice");
  return layout;
}

}  // namespace rcand::plugins::pca9685
