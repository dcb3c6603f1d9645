#include "settings.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <set>

#include "protocol.hpp"
#include "sts_table.hpp"

namespace rcand::plugins::feetech {

namespace {

using nlohmann::json;
using sdk::ConfigError;

// The STS/SCS Baud Rate register's rates (lerobot tables.py STS_SMS_SERIES_BAUDRATE_TABLE).
constexpr std::array kFeetechBaudRates{1000000, 500000, 250000, 128000, 115200, 57600, 38400, 19200};

std::optional<double> feetech_number(const json& item, const char* key, const std::string& where) {
  const auto it = item.find(key);
  if (it == item.end() || it->is_null()) return std::nullopt;
  if (!it->is_number() || !std::isfinite(it->get<double>()))
    throw ConfigError(where + "." + key + ": expected a number, found " + it->dump());
  return it->get<double>();
}

// The joint's bounds from physics.kinematics[]: rcand's {joint, min_deg, max_deg} or the OpenCastor presets'
// {id, limits_deg: [lo, hi]}.
void feetech_kinematics_limits(const sdk::ConfigView& robot, FeetechServoSettings& servo) {
  const sdk::ConfigView kinematics = robot.sub("physics.kinematics");  // raw() refers into it: keep it alive
  const json& items = kinematics.raw();
  if (!items.is_array()) return;
  for (std::size_t i = 0; i < items.size(); ++i) {
    const json& item = items[i];
    if (!item.is_object() || (item.value("joint", json()) != servo.name && item.value("id", json()) != servo.name)) continue;
    const std::string where = "physics.kinematics[" + std::to_string(i) + "]";
    if (!servo.min_deg) servo.min_deg = feetech_number(item, "min_deg", where);
    if (!servo.max_deg) servo.max_deg = feetech_number(item, "max_deg", where);
    const auto limits = item.find("limits_deg");
    if (limits != item.end() && limits->is_array() && limits->size() == 2 && (*limits)[0].is_number() &&
        (*limits)[1].is_number()) {
      if (!servo.min_deg) servo.min_deg = (*limits)[0].get<double>();
      if (!servo.max_deg) servo.max_deg = (*limits)[1].get<double>();
    }
  }
}

FeetechServoSettings parse_feetech_servo(const json& item, const std::string& where, const sdk::ConfigView& robot) {
  if (!item.is_object()) throw ConfigError(where + ": expected {id, joint} or {id, wheel}, found " + item.dump());
  FeetechServoSettings servo;
  const auto id = item.find("id");
  if (id == item.end() || !id->is_number_integer() || id->get<long long>() < 0 || id->get<long long>() > kMaxId)
    throw ConfigError(where + ".id: expected the servo's ID 0..253, found " + (id == item.end() ? "nothing" : id->dump()));
  servo.id = static_cast<std::uint8_t>(id->get<long long>());
  const bool joint = item.contains("joint"), wheel = item.contains("wheel");
  if (joint == wheel) throw ConfigError(where + ": give exactly one of joint (an arm joint's name) or wheel (left or right)");
  if (item.contains("model")) {
    if (!item["model"].is_string() || !find_model(item["model"].get<std::string>()))
      throw ConfigError(where + ".model: expected sts3215 or sts3250, found " + item["model"].dump());
    servo.model = std::string(find_model(item["model"].get<std::string>())->name);
  }
  if (item.contains("invert")) {
    if (!item["invert"].is_boolean()) throw ConfigError(where + ".invert: expected true or false");
    servo.invert = item["invert"].get<bool>();
  }
  if (const auto pct = feetech_number(item, "torque_limit_pct", where)) {
    if (*pct <= 0 || *pct > 100) throw ConfigError(where + ".torque_limit_pct: expected above 0 and at most 100");
    servo.torque_limit_pct = *pct;
  }
  if (joint) {
    if (!item["joint"].is_string() || item["joint"].get<std::string>().empty())
      throw ConfigError(where + ".joint: expected a joint name, found " + item["joint"].dump());
    servo.name = item["joint"].get<std::string>();
    servo.min_deg = feetech_number(item, "min_deg", where);
    servo.max_deg = feetech_number(item, "max_deg", where);
    servo.offset_deg = feetech_number(item, "offset_deg", where).value_or(0.0);
    servo.max_velocity_dps = feetech_number(item, "max_velocity_dps", where);
    if (servo.max_velocity_dps && *servo.max_velocity_dps <= 0)
      throw ConfigError(where + ".max_velocity_dps: expected a speed above 0");
    feetech_kinematics_limits(robot, servo);
    if (servo.min_deg && servo.max_deg && *servo.min_deg >= *servo.max_deg)
      throw ConfigError(where + ": min_deg must be below max_deg");
  } else {
    const json& side = item["wheel"];
    if (side != "left" && side != "right") throw ConfigError(where + ".wheel: expected left or right, found " + side.dump());
    servo.role = side == "left" ? FeetechServoSettings::Role::LeftWheel : FeetechServoSettings::Role::RightWheel;
    servo.name = side.get<std::string>();
  }
  return servo;
}

long long feetech_integer(const sdk::ConfigView& config, const char* key, long long fallback, long long min, long long max) {
  const long long value = config.get<long long>(key).value_or(fallback);
  if (value < min || value > max)
    throw ConfigError(std::string(key) + ": expected an integer in [" + std::to_string(min) + ", " + std::to_string(max) +
                      "], found " + std::to_string(value));
  return value;
}

}  // namespace

bool FeetechSettings::has_wheels() const {
  return std::any_of(servos.begin(), servos.end(), [](const auto& s) { return s.role != FeetechServoSettings::Role::Joint; });
}
bool FeetechSettings::has_joints() const {
  return std::any_of(servos.begin(), servos.end(), [](const auto& s) { return s.role == FeetechServoSettings::Role::Joint; });
}

FeetechSettings FeetechSettings::from(const sdk::ConfigView& driver, const sdk::ConfigView& robot) {
  FeetechSettings s;
  const auto port = driver.get<std::string>("port");
  if (!port || port->empty())
    throw ConfigError("port: required, the serial device of the bus (/dev/ttyACM0, /dev/serial/by-id/...)");
  s.port = *port;
  s.baud_rate = static_cast<int>(driver.get<long long>("baud_rate").value_or(s.baud_rate));
  if (std::find(kFeetechBaudRates.begin(), kFeetechBaudRates.end(), s.baud_rate) == kFeetechBaudRates.end())
    throw ConfigError("baud_rate: " + std::to_string(s.baud_rate) +
                      " is not a Feetech rate (1000000, 500000, 250000, 128000, 115200, 57600, 38400, 19200)");

  const json& raw = driver.raw();
  const auto servos = raw.find("servos");
  if (servos == raw.end() || !servos->is_array() || servos->empty())
    throw ConfigError("servos: required, a list of {id, joint} (arm) or {id, wheel: left|right} (drive) items");
  // A bus-wide model applies to every servo that names none.
  std::optional<std::string> model;
  if (const auto name = driver.get<std::string>("model")) {
    if (!find_model(*name)) throw ConfigError("model: expected sts3215 or sts3250, found \"" + *name + "\"");
    model = std::string(find_model(*name)->name);
  }
  std::set<int> ids;
  std::set<std::string> names;
  for (std::size_t i = 0; i < servos->size(); ++i) {
    const std::string where = "servos[" + std::to_string(i) + "]";
    auto servo = parse_feetech_servo((*servos)[i], where, robot);
    if (!servo.model) servo.model = model;
    if (!ids.insert(servo.id).second) throw ConfigError(where + ".id: " + std::to_string(servo.id) + " is used twice");
    if (!names.insert(servo.name).second) throw ConfigError(where + ": '" + servo.name + "' is named twice");
    s.servos.push_back(std::move(servo));
  }
  if (s.has_wheels() && !(names.count("left") && names.count("right")))
    throw ConfigError("servos: a drive needs both a left and a right wheel");

  s.poll_hz = driver.get<double>("poll_hz").value_or(s.poll_hz);
  if (!std::isfinite(s.poll_hz) || s.poll_hz < 1 || s.poll_hz > 500)
    throw ConfigError("poll_hz: expected 1..500, found " + json(s.poll_hz).dump());
  s.reply_timeout = std::chrono::milliseconds(feetech_integer(driver, "reply_timeout_ms", 20, 1, 500));
  s.retries = static_cast<unsigned>(feetech_integer(driver, "retries", 2, 0, 10));
  s.lost_after_polls = static_cast<unsigned>(feetech_integer(driver, "lost_after_polls", 3, 1, 100));
  s.halt_deadline = std::chrono::milliseconds(feetech_integer(driver, "halt_deadline_ms", 5, 1, 100));
  s.command_timeout = std::chrono::milliseconds(feetech_integer(driver, "command_timeout_ms", 100, 1, 2000));
  s.joint_velocity_dps = driver.get<double>("joint_velocity_dps").value_or(s.joint_velocity_dps);
  if (!std::isfinite(s.joint_velocity_dps) || s.joint_velocity_dps <= 0)
    throw ConfigError("joint_velocity_dps: expected a speed above 0");
  s.wheel_max_rpm = driver.get<double>("wheel_max_rpm");
  if (s.wheel_max_rpm && (!std::isfinite(*s.wheel_max_rpm) || *s.wheel_max_rpm <= 0))
    throw ConfigError("wheel_max_rpm: expected a speed above 0");
  return s;
}

}  // namespace rcand::plugins::feetech
