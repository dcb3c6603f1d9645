#include "joint_limits.hpp"

#include <algorithm>
#include <cmath>
#include <set>

namespace rcand::plugins::arm {

namespace {

using nlohmann::json;

// A finite number at item[key], or nullopt when absent; throws naming the key otherwise.
std::optional<double> number_at(const json& item, const char* key, const std::string& at) {
  const auto it = item.find(key);
  if (it == item.end() || it->is_null()) return std::nullopt;
  if (!it->is_number() || !std::isfinite(it->get<double>()))
    throw sdk::ConfigError(at + "." + key + ": expected a number, found " + it->dump());
  return it->get<double>();
}

double positive_at(const json& item, const char* key, const std::string& at, double fallback) {
  const double value = number_at(item, key, at).value_or(fallback);
  if (value <= 0.0) throw sdk::ConfigError(at + "." + key + ": expected a number > 0, found " + json(value).dump());
  return value;
}

bool names_joint(const json& item) { return item.is_object() && item.contains("joint"); }

}  // namespace

std::vector<JointLimit> parse_joint_limits(const json& items, const std::string& where) {
  if (!items.is_array()) throw sdk::ConfigError(where + ": expected a list of joints, found " + std::string(items.type_name()));
  std::vector<JointLimit> joints;
  std::set<std::string> seen;
  for (std::size_t i = 0; i < items.size(); ++i) {
    const json& item = items[i];
    const std::string at = where + "[" + std::to_string(i) + "]";
    if (!names_joint(item)) continue;  // a link description: dimensions only, nothing to limit
    JointLimit j;
    if (!item["joint"].is_string() || item["joint"].get<std::string>().empty())
      throw sdk::ConfigError(at + ".joint: expected a non-empty string, found " + item["joint"].dump());
    j.joint = item["joint"].get<std::string>();
    if (!seen.insert(j.joint).second) throw sdk::ConfigError(at + ".joint: joint '" + j.joint + "' is listed twice");
    // No default range: an arm with a guessed range is an arm that hits its own frame.
    const auto min = number_at(item, "min_deg", at), max = number_at(item, "max_deg", at);
    if (!min) throw sdk::ConfigError(at + ".min_deg: required for joint '" + j.joint + "' (its lower limit in degrees)");
    if (!max) throw sdk::ConfigError(at + ".max_deg: required for joint '" + j.joint + "' (its upper limit in degrees)");
    if (*min >= *max)
      throw sdk::ConfigError(at + ": joint '" + j.joint + "' needs min_deg < max_deg, found " + json(*min).dump() + " and " +
                             json(*max).dump());
    j.min_deg = *min;
    j.max_deg = *max;
    j.max_velocity_dps = positive_at(item, "max_velocity_dps", at, JointLimit::kDefaultVelocityDps);
    if (j.max_velocity_dps < JointLimit::kMinVelocityDps)
      throw sdk::ConfigError(at + ".max_velocity_dps: " + json(j.max_velocity_dps).dump() + " is below the slowest speed a " +
                             "command may ask for, " + json(JointLimit::kMinVelocityDps).dump() + " deg/s");
    j.max_step_deg = positive_at(item, "max_step_deg", at, JointLimit::kDefaultStepDeg);
    j.home_deg = number_at(item, "home_deg", at).value_or(std::clamp(0.0, j.min_deg, j.max_deg));
    if (j.home_deg < j.min_deg || j.home_deg > j.max_deg)
      throw sdk::ConfigError(at + ".home_deg: " + json(j.home_deg).dump() + " is outside joint '" + j.joint + "' range [" +
                             json(j.min_deg).dump() + ", " + json(j.max_deg).dump() + "]");
    joints.push_back(std::move(j));
  }
  return joints;
}

std::vector<JointLimit> joint_limits_from(const sdk::ConfigView& robot_config, const std::optional<std::string>& driver_id,
                                          std::string& where) {
  const json kinematics = robot_config.sub("physics.kinematics").raw();  // copies: sub() returns a temporary view
  if (kinematics.is_array() && std::any_of(kinematics.begin(), kinematics.end(), names_joint)) {
    where = "physics.kinematics";
    return parse_joint_limits(kinematics, where);
  }
  const json drivers = robot_config.sub("drivers").raw();
  if (!drivers.is_array()) return {};
  for (const json& entry : drivers) {
    if (!entry.is_object() || !entry.contains("joints")) continue;
    const auto id_it = entry.find("id");
    const std::string id = id_it != entry.end() && id_it->is_string() ? id_it->get<std::string>() : std::string();
    if (driver_id && id != *driver_id) continue;
    where = "drivers[" + id + "].joints";
    return parse_joint_limits(entry["joints"], where);
  }
  return {};
}

const JointLimit* find_joint(const std::vector<JointLimit>& joints, std::string_view name) noexcept {
  for (const auto& j : joints)
    if (j.joint == name) return &j;
  return nullptr;
}

}  // namespace rcand::plugins::arm
