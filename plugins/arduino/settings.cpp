#include "settings.hpp"

#include <algorithm>
#include <array>
#include <cmath>

namespace rcand::plugins::arduino {

namespace {

using nlohmann::json;
using sdk::ConfigError;

constexpr std::array kArduinoBauds{9600, 19200, 38400, 57600, 115200, 230400, 460800, 500000};
constexpr std::array<const char*, 6> kArduinoChannelKeys{"left_pwm_pin",  "left_dir_a",  "left_dir_b",
                                                         "right_pwm_pin", "right_dir_a", "right_dir_b"};

long long arduino_integer(const sdk::ConfigView& config, const std::string& prefix, const char* key, long long fallback,
                          long long min, long long max) {
  const auto found = config.raw().is_object() ? config.raw().find(key) : config.raw().end();
  if (!config.raw().is_object() || found == config.raw().end() || found->is_null()) return fallback;
  if (!found->is_number_integer() || found->get<long long>() < min || found->get<long long>() > max)
    throw ConfigError(prefix + key + ": expected an integer in [" + std::to_string(min) + ", " + std::to_string(max) +
                      "], found " + found->dump());
  return found->get<long long>();
}

double arduino_number(const sdk::ConfigView& config, const std::string& prefix, const char* key, double fallback, double min,
                      double max) {
  const auto found = config.raw().is_object() ? config.raw().find(key) : config.raw().end();
  if (!config.raw().is_object() || found == config.raw().end() || found->is_null()) return fallback;
  if (!found->is_number() || !std::isfinite(found->get<double>()) || found->get<double>() < min || found->get<double>() > max)
    throw ConfigError(prefix + key + ": expected a number in [" + std::to_string(min) + ", " + std::to_string(max) + "], found " +
                      found->dump());
  return found->get<double>();
}

bool arduino_flag(const sdk::ConfigView& config, const std::string& prefix, const char* key) {
  const auto found = config.raw().find(key);
  if (found == config.raw().end() || found->is_null()) return false;
  if (!found->is_boolean()) throw ConfigError(prefix + key + ": expected true or false, found " + found->dump());
  return found->get<bool>();
}

UltrasonicSettings arduino_parse_ultrasonic(const sdk::ConfigView& block) {
  const std::string prefix = "ultrasonic.";
  if (!block.raw().is_object()) throw ConfigError("ultrasonic: expected {sensor_type: hcsr04, ...}, found " + block.raw().dump());
  UltrasonicSettings u;
  if (const auto type = block.raw().find("sensor_type"); type != block.raw().end()) {
    if (!type->is_string() || type->get<std::string>().empty())
      throw ConfigError("ultrasonic.sensor_type: expected the firmware's sensor id (hcsr04), found " + type->dump());
    u.sensor_id = type->get<std::string>();
  }
  u.poll_hz = arduino_number(block, prefix, "poll_hz", u.poll_hz, 1.0, 40.0);
  u.stale_after = std::chrono::milliseconds(arduino_integer(block, prefix, "stale_ms", u.stale_after.count(), 50, 5000));
  if (u.stale_after.count() * u.poll_hz < 2000.0)
    throw ConfigError("ultrasonic.stale_ms: less than two polls (poll_hz): every reading would be stale before the next");
  u.max_range_cm = arduino_number(block, prefix, "max_range_cm", u.max_range_cm, 2.0, 1000.0);
  if (const auto no_echo = block.raw().find("no_echo"); no_echo != block.raw().end()) {
    if (*no_echo != "unavailable" && *no_echo != "clear")
      throw ConfigError("ultrasonic.no_echo: expected unavailable or clear, found " + no_echo->dump());
    u.no_echo_is_clear = *no_echo == "clear";
  }
  (void)arduino_integer(block, prefix, "trigger_pin", 0, 0, 69);
  (void)arduino_integer(block, prefix, "echo_pin", 0, 0, 69);
  return u;
}

}  // namespace

int ArduinoSettings::pwm_of(double fraction, bool invert) const {
  if (!std::isfinite(fraction)) return 0;
  fraction = std::clamp(fraction, -1.0, 1.0);
  if (invert) fraction = -fraction;
  if (std::abs(fraction) < 1e-6) return 0;
  const double magnitude =
      std::clamp(std::abs(fraction) * max_pwm, static_cast<double>(deadband_pwm), static_cast<double>(max_pwm));
  const int pwm = static_cast<int>(std::lround(magnitude));
  return fraction > 0 ? pwm : -pwm;
}

ArduinoSettings ArduinoSettings::from(const sdk::ConfigView& driver) {
  ArduinoSettings s;
  const auto port = driver.get<std::string>("port");
  if (!port || port->empty())
    throw ConfigError("port: required, the Arduino's serial device (/dev/ttyACM0, /dev/serial/by-id/...)");
  s.port = *port;
  if (driver.has("baud") && driver.has("baud_rate")) throw ConfigError("baud_rate: give baud or baud_rate, not both");
  const char* baud_key = driver.has("baud_rate") ? "baud_rate" : "baud";
  s.baud = static_cast<int>(arduino_integer(driver, "", baud_key, s.baud, 1, 4'000'000));
  if (std::find(kArduinoBauds.begin(), kArduinoBauds.end(), s.baud) == kArduinoBauds.end())
    throw ConfigError(std::string(baud_key) + ": " + std::to_string(s.baud) +
                      " is not a rate the port can be set to (the bridge firmware uses 115200)");
  s.max_pwm = static_cast<int>(arduino_integer(driver, "", "max_pwm", s.max_pwm, 1, 255));
  s.deadband_pwm = static_cast<int>(arduino_integer(driver, "", "deadband_pwm", s.deadband_pwm, 0, 255));
  if (s.deadband_pwm > s.max_pwm) throw ConfigError("deadband_pwm: must not exceed max_pwm");
  s.invert_left = arduino_flag(driver, "", "invert_left");
  s.invert_right = arduino_flag(driver, "", "invert_right");
  s.reply_timeout = std::chrono::milliseconds(std::lround(arduino_number(driver, "", "timeout_s", 0.2, 0.05, 2.0) * 1000.0));
  s.heartbeat = std::chrono::milliseconds(arduino_integer(driver, "", "heartbeat_ms", s.heartbeat.count(), 50, 500));
  s.halt_deadline = std::chrono::milliseconds(arduino_integer(driver, "", "halt_deadline_ms", s.halt_deadline.count(), 1, 100));
  s.boot_timeout = std::chrono::milliseconds(arduino_integer(driver, "", "boot_timeout_ms", s.boot_timeout.count(), 100, 10000));
  s.command_timeout =
      std::chrono::milliseconds(arduino_integer(driver, "", "command_timeout_ms", s.command_timeout.count(), 10, 2000));
  if (const auto channels = driver.sub("channels"); driver.has("channels")) {
    if (!channels.raw().is_object()) throw ConfigError("channels: expected the firmware's pins {left_pwm_pin: 5, ...}");
    for (const char* key : kArduinoChannelKeys)
      if (channels.has(key)) s.channels[key] = static_cast<int>(arduino_integer(channels, "channels.", key, 0, 0, 69));
  }
  if (driver.has("ultrasonic")) s.ultrasonic = arduino_parse_ultrasonic(driver.sub("ultrasonic"));
  return s;
}

}  // namespace rcand::plugins::arduino
