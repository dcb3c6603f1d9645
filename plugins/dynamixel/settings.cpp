#include "settings.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <set>

namespace rcand::plugins::dynamixel {

namespace {

using nlohmann::json;
using sdk::ConfigError;

// The rates the X and P series can be set to (Baud Rate register, address 8).
constexpr std::array kBaudRates{9600, 57600, 115200, 1000000, 2000000, 3000000, 4000000, 4500000};

std::optional<double> number_at(const json& item, const char* key, const std::string& where) {
  const auto it = item.find(key);
  if (it == item.end() || it->is_null()) return std::nullopt;
  if (!it->is_number() || !std::isfinite(it->get<double>()))
    throw ConfigError(where + "." + key + ": expected a number, found " + it->dump());
  return it->get<double>();
}

// The joint's bounds from physics.kinematics[] (the item whose `joint` is `name`), if any.
void kinematics_limits(const sdk::ConfigView& robot, ServoSettings& servo) {
  const sdk::ConfigView kinematics = robot.sub("physics.kinematics");
  const json& items = kinematics.raw();
  if (!items.is_array()) return;
  for (std::size_t i = 0; i < items.size(); ++i) {
    const json& item = items[i];
    if (!item.is_object() || item.value("joint", json()) != servo.name) continue;
    const std::string where = "physics.kinematics[" + std::to_string(i) + "]";
    if (!servo.min_deg) servo.min_deg = number_at(item, "min_deg", where);
    if (!servo.max_deg) servo.max_deg = number_at(item, "max_deg", where);
  }
}

ServoSettings parse_servo(const json& item, const std::string& where, const sdk::ConfigView& robot) {
  if (!item.is_object()) throw ConfigError(where + ": expected {id, joint} or {id, wheel}, found " + item.dump());
  ServoSettings servo;
  const auto id = item.find("id");
  if (id == item.end() || !id->is_number_integer() || id->get<long long>() < 0 || id->get<long long>() > 252)
    throw ConfigError(where + ".id: expected the servo's Dynamixel ID 0..252, found " +
                      (id == item.end() ? "nothing" : id->dump()));
  servo.id = static_cast<std::uint8_t>(id->get<long long>());
  const bool joint = item.contains("joint"), wheel = item.contains("wheel");
  if (joint == wheel) throw ConfigError(where + ": give exactly one of joint (an arm joint's name) or wheel (left or right)");
  if (joint) {
    if (!item["joint"].is_string() || item["joint"].get<std::string>().empty())
      throw ConfigError(where + ".joint: expected a joint name, found " + item["joint"].dump());
    servo.name = item["joint"].get<std::string>();
    servo.min_deg = number_at(item, "min_deg", where);
    servo.max_deg = number_at(item, "max_deg", where);
    kinematics_limits(robot, servo);
    if (servo.min_deg && servo.max_deg && *servo.min_deg >= *servo.max_deg)
      throw ConfigError(where + ": min_deg must be below max_deg");
  } else {
    const json& side = item["wheel"];
    if (side != "left" && side != "right") throw ConfigError(where + ".wheel: expected left or right, found " + side.dump());
    servo.role = side == "left" ? ServoSettings::Role::LeftWheel : ServoSettings::Role::RightWheel;
    servo.name = side.get<std::string>();
    if (item.contains("reverse")) {
      if (!item["reverse"].is_boolean()) throw ConfigError(where + ".reverse: expected true or false");
      servo.reverse = item["reverse"].get<bool>();
    }
  }
  return servo;
}

long long integer(const sdk::ConfigView& config, const char* key, long long fallback, long long min, long long max) {
  const long long value = config.get<long long>(key).value_or(fallback);
  if (value < min || value > max)
    throw ConfigError(std::string(key) + ": expected an integer in [" + std::to_string(min) + ", " + std::to_string(max) +
                      "], found " + std::to_string(value));
  return value;
}

}  // namespace

bool DynamixelSettings::has_wheels() const {
  return std::any_of(servos.begin(), servos.end(), [](const auto& s) { return s.role != ServoSettings::Role::Joint; });
}
bool DynamixelSettings::has_joints() const {
  return std::any_of(servos.begin(), servos.end(), [](const auto& s) { return s.role == ServoSettings::Role::Joint; });
}
std::uint8_t DynamixelSettings::watchdog_units() const { return static_cast<std::uint8_t>((watchdog.count() + 19) / 20); }

DynamixelSettings DynamixelSettings::from(const sdk::ConfigView& driver, const sdk::ConfigView& robot) {
  DynamixelSettings s;
  const auto port = driver.get<std::string>("port");
  if (!port || port->empty())
    throw ConfigError("port: required, the serial device of the bus (/dev/ttyUSB0, /dev/serial/by-id/...)");
  s.port = *port;
  s.baud_rate = static_cast<int>(driver.get<long long>("baud_rate").value_or(s.baud_rate));
  if (std::find(kBaudRates.begin(), kBaudRates.end(), s.baud_rate) == kBaudRates.end())
    throw ConfigError("baud_rate: " + std::to_string(s.baud_rate) +
                      " is not a Dynamixel rate (9600, 57600, 115200, 1000000, 2000000, 3000000, 4000000, 4500000)");

  const json& raw = driver.raw();
  const auto servos = raw.find("servos");
  if (servos == raw.end() || !servos->is_array() || servos->empty())
    throw ConfigError("servos: required, a list of {id, joint} (arm) or {id, wheel: left|right} (drive) items");
  std::set<int> ids;
  std::set<std::string> names;
  for (std::size_t i = 0; i < servos->size(); ++i) {
    const std::string where = "servos[" + std::to_string(i) + "]";
    auto servo = parse_servo((*servos)[i], where, robot);
    if (!ids.insert(servo.id).second) throw ConfigError(where + ".id: " + std::to_string(servo.id) + " is used twice");
    if (!names.insert(servo.name).second) throw ConfigError(where + ": '" + servo.name + "' is named twice");
    s.servos.push_back(std::move(servo));
  }
  if (s.has_wheels() && !(names.count("left") && names.count("right")))
    throw ConfigError("servos: a drive needs both a left and a right wheel");

  s.watchdog = std::chrono::milliseconds(integer(driver, "watchdog_ms", 100, 0, 2540));
  s.poll_hz = driver.get<double>("poll_hz").value_or(s.poll_hz);
  if (!std::isfinite(s.poll_hz) || s.poll_hz < 1 || s.poll_hz > 500)
    throw ConfigError("poll_hz: expected 1..500, found " + json(s.poll_hz).dump());
  if (s.watchdog.count() > 0 && s.watchdog.count() * s.poll_hz < 2000)
    throw ConfigError("watchdog_ms: " + std::to_string(s.watchdog.count()) + " ms is less than two polls at " +
                      json(s.poll_hz).dump() + " Hz: the servos would stop by themselves while rcand runs");
  s.reply_timeout = std::chrono::milliseconds(integer(driver, "reply_timeout_ms", 20, 1, 500));
  s.halt_deadline = std::chrono::milliseconds(integer(driver, "halt_deadline_ms", 5, 1, 100));
  s.command_timeout = std::chrono::milliseconds(integer(driver, "command_timeout_ms", 100, 1, 2000));
  s.joint_velocity_dps = driver.get<double>("joint_velocity_dps").value_or(s.joint_velocity_dps);
  if (!std::isfinite(s.joint_velocity_dps) || s.joint_velocity_dps <= 0)
    throw ConfigError("joint_velocity_dps: expected a speed above 0");
  s.wheel_max_rpm = driver.get<double>("wheel_max_rpm");
  if (s.wheel_max_rpm && (!std::isfinite(*s.wheel_max_rpm) || *s.wheel_max_rpm <= 0))
    throw ConfigError("wheel_max_rpm: expected a speed above 0");
  s.reboot_on_error = driver.get<bool>("reboot_on_error").value_or(false);
  return s;
}

}  // namespace rcand::plugins::dynamixel
