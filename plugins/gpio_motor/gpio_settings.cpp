#include "gpio_settings.hpp"

#include <cmath>
#include <set>

namespace rcand::plugins::gpio_motor {

namespace {

using nlohmann::json;
using sdk::ConfigError;

LineRef line_ref(const json& value, const std::string& where) {
  if (value.is_number_integer() && value.get<long long>() >= 0 && value.get<long long>() < 1024)
    return static_cast<unsigned>(value.get<long long>());
  if (value.is_string() && !value.get<std::string>().empty()) return value.get<std::string>();
  throw ConfigError(where + ": expected a line offset (17), a line name (\"GPIO17\") or {line, active_low}, found " +
                    value.dump());
}

LineSettings line_settings(const json& value, const std::string& where) {
  if (!value.is_object()) return {line_ref(value, where), false};
  if (!value.contains("line")) throw ConfigError(where + ".line: required");
  LineSettings s{line_ref(value["line"], where + ".line"), false};
  if (value.contains("active_low")) {
    if (!value["active_low"].is_boolean()) throw ConfigError(where + ".active_low: expected true or false");
    s.active_low = value["active_low"].get<bool>();
  }
  return s;
}

MotorSettings motor(const json& channels, const std::string& side) {
  const std::string where = "channels." + side;
  if (!channels.contains(side) || !channels[side].is_object()) throw ConfigError(where + ": required, {in1, in2, enable?, pwm?}");
  const json& m = channels[side];
  MotorSettings s;
  for (const char* key : {"in1", "in2"})
    if (!m.contains(key)) throw ConfigError(where + "." + key + ": required (a direction input of the bridge)");
  s.in1 = line_settings(m["in1"], where + ".in1");
  s.in2 = line_settings(m["in2"], where + ".in2");
  if (m.contains("enable") && !m["enable"].is_null()) s.enable = line_settings(m["enable"], where + ".enable");
  if (m.contains("pwm") && !m["pwm"].is_null()) {
    const json& p = m["pwm"];
    if (!p.is_object()) throw ConfigError(where + ".pwm: expected {chip, channel, frequency_hz}");
    PwmSettings pwm;
    for (const char* key : {"chip", "channel"}) {
      if (!p.contains(key)) continue;
      if (!p[key].is_number_integer() || p[key].get<long long>() < 0 || p[key].get<long long>() > 255)
        throw ConfigError(where + ".pwm." + key + ": expected 0..255, found " + p[key].dump());
      (std::string(key) == "chip" ? pwm.chip : pwm.channel) = static_cast<unsigned>(p[key].get<long long>());
    }
    if (p.contains("frequency_hz")) {
      if (!p["frequency_hz"].is_number() || !std::isfinite(p["frequency_hz"].get<double>()) ||
          p["frequency_hz"].get<double>() < 1 || p["frequency_hz"].get<double>() > 1e6)
        throw ConfigError(where + ".pwm.frequency_hz: expected 1..1000000");
      pwm.frequency_hz = p["frequency_hz"].get<double>();
    }
    s.pwm = pwm;
  }
  if (m.contains("reverse")) {
    if (!m["reverse"].is_boolean()) throw ConfigError(where + ".reverse: expected true or false");
    s.reverse = m["reverse"].get<bool>();
  }
  return s;
}

}  // namespace

std::optional<std::string> GpioMotorSettings::first_line_name() const {
  for (const MotorSettings* m : {&left, &right})
    for (const LineSettings* l : {&m->in1, &m->in2, m->enable ? &*m->enable : nullptr})
      if (l)
        if (const auto* name = std::get_if<std::string>(&l->line)) return *name;
  if (standby)
    if (const auto* name = std::get_if<std::string>(&standby->line)) return *name;
  return std::nullopt;
}

GpioMotorSettings GpioMotorSettings::from(const sdk::ConfigView& config) {
  GpioMotorSettings s;
  const json& raw = config.raw();
  if (raw.contains("chip") && !raw["chip"].is_null()) {
    if (raw["chip"].is_number_integer() && raw["chip"].get<long long>() >= 0)
      s.chip = std::to_string(raw["chip"].get<long long>());
    else if (raw["chip"].is_string() && !raw["chip"].get<std::string>().empty()) s.chip = raw["chip"].get<std::string>();
    else
      throw ConfigError("chip: expected a chip label (pinctrl-rp1), name (gpiochip4), path or number, found " +
                        raw["chip"].dump());
  }
  const json channels = raw.value("channels", json::object());
  if (!channels.is_object()) throw ConfigError("channels: expected {left: {in1, in2, ...}, right: {...}}");
  s.left = motor(channels, "left");
  s.right = motor(channels, "right");
  if (raw.contains("standby") && !raw["standby"].is_null()) s.standby = line_settings(raw["standby"], "standby");
  // One line drives one thing: a line named twice would let one motor's stop be another's start.
  std::set<std::string> seen;
  if (s.standby) seen.insert(describe(s.standby->line));
  for (const auto& [side, m] : {std::pair{"left", &s.left}, std::pair{"right", &s.right}})
    for (const auto& [key, l] :
         {std::pair{"in1", &m->in1}, std::pair{"in2", &m->in2}, std::pair{"enable", m->enable ? &*m->enable : nullptr}}) {
      if (!l) continue;
      if (!seen.insert(describe(l->line)).second)
        throw ConfigError(std::string("channels.") + side + "." + key + ": " + describe(l->line) + " is used twice");
    }
  // Likewise a PWM channel: the second motor's duty would overwrite the first's.
  if (s.left.pwm && s.right.pwm && s.left.pwm->chip == s.right.pwm->chip && s.left.pwm->channel == s.right.pwm->channel)
    throw ConfigError("channels.right.pwm: pwmchip" + std::to_string(s.right.pwm->chip) + " channel " +
                      std::to_string(s.right.pwm->channel) + " is used twice: each motor needs its own PWM channel");
  return s;
}

}  // namespace rcand::plugins::gpio_motor
