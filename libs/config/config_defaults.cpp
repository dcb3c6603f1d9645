#include "libs/config/config_defaults.hpp"

#include "libs/config/config_schema.hpp"
#include "libs/config/driver_protocols.hpp"

#include <algorithm>
#include <map>
#include <set>

namespace rcand::config {
namespace {

void add_warning(const RobotConfig& config, std::vector<ConfigDiagnostic>& warnings, const std::string& key_path,
                 std::string message) {
  warnings.push_back({ConfigDiagnostic::Severity::Warning, config.mark_of(key_path), key_path, std::move(message)});
}

std::string in_quotes(std::string_view text) { return "\"" + std::string(text) + "\""; }

// RCAN ids are names, not secrets: the RURI segments (robot_ruri) are cleaned again anyway.
void default_identity(RobotConfig& c, std::vector<ConfigDiagnostic>& warnings) {
  if (c.model.empty()) {
    c.model = model_slug(c.robot_name);
    add_warning(c, warnings, "metadata.model",
                "not set: the model is " + in_quotes(c.model) +
                    ", from metadata.robot_name (it names the robot in its RURI "
                    "and in discovery); set metadata.model to name it");
  }
  if (c.manufacturer.empty()) {
    c.manufacturer = std::string(kUnknownManufacturer);
    add_warning(c, warnings, "metadata.manufacturer",
                "not set: the manufacturer is " + in_quotes(kUnknownManufacturer) +
                    " (it names the robot in its RURI); set "
                    "metadata.manufacturer to name it");
  }
}

void read_rcan_version(const RobotConfig& c, std::vector<ConfigDiagnostic>& warnings) {
  const auto major = detail::rcan_major_version(c.rcan_version);
  if (!major || *major == 1) return;
  add_warning(c, warnings, "rcan_version",
              "the file is written for RCAN " + c.rcan_version +
                  "; rcand implements RCAN 1.3 (1.3.0) and reads it as 1.3: "
                  "the keys 1.3 defines are used as 1.3 defines them, the others are ignored");
}

// Other runtimes' names for the hardware rcand's plugins drive, then ids for drivers that have none:
// `<protocol><index>` (index among the drivers of that protocol, from 0; `_` before it when the protocol ends in a
// digit, "pca9685_0"), the next index when a written id already has that name.
void name_drivers(RobotConfig& c, std::vector<ConfigDiagnostic>& warnings) {
  std::set<std::string> taken;
  for (const auto& driver : c.drivers)
    if (!driver.id.empty()) taken.insert(driver.id);
  std::map<std::string, int> seen;  // protocol -> drivers of it so far
  for (std::size_t i = 0; i < c.drivers.size(); ++i) {
    auto& driver = c.drivers[i];
    const std::string path = "drivers[" + std::to_string(i) + "]";
    if (const auto alias = protocol_alias(driver.protocol)) {
      add_warning(c, warnings, path + ".protocol",
                  in_quotes(driver.protocol) + " is read as rcand's protocol " + in_quotes(alias->protocol) + " (" +
                      std::string(alias->hardware) + "); write " + in_quotes(alias->protocol) +
                      " to say so (a plugin that provides " + in_quotes(driver.protocol) + " itself serves it instead)");
      driver.written_protocol = driver.protocol;
      driver.protocol = std::string(alias->protocol);
      driver.settings["protocol"] = driver.protocol;
    }
    int index = seen[driver.protocol]++;
    if (!driver.id.empty()) continue;
    const bool digit_last = !driver.protocol.empty() && driver.protocol.back() >= '0' && driver.protocol.back() <= '9';
    const std::string stem = driver.protocol + (digit_last ? "_" : "");
    while (taken.contains(stem + std::to_string(index))) ++index;
    driver.id = stem + std::to_string(index);
    taken.insert(driver.id);
    driver.settings["id"] = driver.id;
    add_warning(c, warnings, path,
                "no 'id': this driver is " + in_quotes(driver.id) +
                    " (<protocol><index>; the API and the logs name it so); set "
                    "id to name it");
  }
}

// §10.2: no nav without the two physics fields. §9.5: the config stays authoritative for the rest of its list.
void drop_nav_without_physics(RobotConfig& c, std::vector<ConfigDiagnostic>& warnings) {
  if (!c.capabilities || (c.wheel_circumference_m && c.turn_time_per_deg_s)) return;
  auto& listed = *c.capabilities;
  const auto nav = std::find(listed.begin(), listed.end(), "nav");
  if (nav == listed.end()) return;
  std::string missing;
  if (!c.wheel_circumference_m) missing = "physics.wheel_circumference_m";
  if (!c.turn_time_per_deg_s) missing += std::string(missing.empty() ? "" : " and ") + "physics.turn_time_per_deg_s";
  add_warning(c, warnings, "rcan_protocol.capabilities[" + std::to_string(nav - listed.begin()) + "]",
              "'nav' is listed, but " + missing + (missing.find(" and ") == std::string::npos ? " is" : " are") +
                  " missing (§10.2: without physics.wheel_circumference_m and physics.turn_time_per_deg_s a robot must not "
                  "advertise nav): the robot starts without nav and advertises the rest of this list as written (§9.5)");
  listed.erase(std::remove(listed.begin(), listed.end(), "nav"), listed.end());
}

}  // namespace

std::string model_slug(std::string_view robot_name) {
  std::string slug;
  for (const char raw : robot_name) {
    const char c = (raw >= 'A' && raw <= 'Z') ? static_cast<char>(raw - 'A' + 'a') : raw;
    if ((c >= 'a' && c <= 'z') || (c >= '0' && c <= '9')) slug.push_back(c);
    else if (!slug.empty() && slug.back() != '-') slug.push_back('-');
  }
  while (!slug.empty() && slug.back() == '-') slug.pop_back();
  return slug.empty() ? "robot" : slug;
}

void apply_config_defaults(RobotConfig& config, std::vector<ConfigDiagnostic>& warnings) {
  read_rcan_version(config, warnings);
  default_identity(config, warnings);
  name_drivers(config, warnings);
  drop_nav_without_physics(config, warnings);
}

}  // namespace rcand::config
