#include "kernel/registry/capability_registry.hpp"

#include "libs/config/config_schema.hpp"

#include <algorithm>
#include <array>
#include <set>

namespace rcand::kernel {
namespace {

using sdk::Scope;

std::vector<std::string> standard_names() {
  std::vector<std::string> names;
  for (const auto& cap : standard_capabilities()) names.emplace_back(cap.name);
  return names;
}

[[noreturn]] void fail(const RobotConfig& config, const std::string& path, std::string message) {
  ConfigDiagnostic diagnostic;
  diagnostic.severity = ConfigDiagnostic::Severity::Error;
  diagnostic.mark = config.mark_of(path);
  diagnostic.key_path = path;
  diagnostic.message = std::move(message);
  throw ConfigError({std::move(diagnostic)});
}

std::string join(const std::vector<std::string>& items, std::string_view separator) {
  std::string out;
  for (const auto& item : items) {
    if (!out.empty()) out += separator;
    out += item;
  }
  return out;
}

void add_unique(std::vector<std::string>& names, std::string name) {
  if (std::find(names.begin(), names.end(), name) == names.end()) names.push_back(std::move(name));
}

// §9.3 (with the names other runtimes write for the same hardware), plus: any driver implementing differential_drive
// implies teleop (and nav when physics allows), any implementing joint_arm implies arm. One reading of the table:
// with physics.kinematics, dynamixel drivers are the arm's servos and imply arm only - an arm advertising teleop
// would answer every drive with 503 (a robot that also drives on Dynamixel wheels lists its capabilities).
std::vector<std::string> auto_detect(const RobotConfig& config, const ProviderLookup& lookup, std::vector<std::string>& notes) {
  std::vector<std::string> found{"status"};
  bool drive = false, arm = false;
  for (const auto& driver : config.drivers) {
    const std::string& p = driver.protocol;
    const bool dynamixel = p == "dynamixel" || p == "dynamixel_v2";
    const auto interface = lookup.driver_interface ? lookup.driver_interface(p) : std::nullopt;
    if ((dynamixel && !config.has_kinematics) || p == "pca9685" || p == "pca9685_i2c" || interface == "differential_drive")
      drive = true;
    if ((dynamixel && config.has_kinematics) || interface == "joint_arm") arm = true;
  }
  if (arm && !drive && config.has_kinematics)
    notes.emplace_back(
        "dynamixel drivers with physics.kinematics read as an arm: arm, not teleop or nav (list "
        "rcan_protocol.capabilities for a robot that also drives on them)");
  if (drive) {
    if (has_nav_physics(config)) add_unique(found, std::string(kNavCapability));
    else
      notes.emplace_back("nav not declared: physics.wheel_circumference_m and physics.turn_time_per_deg_s are required (§10.2)");
    add_unique(found, std::string(kTeleopCapability));
  }
  if (config.has_camera) add_unique(found, std::string(kVisionCapability));
  if (config.has_agent) add_unique(found, std::string(kChatCapability));
  if (arm) add_unique(found, std::string(kArmCapability));
  return found;
}

bool config_flag_set(const nlohmann::json& doc, std::string_view dotted) {
  const nlohmann::json* node = &doc;
  for (std::size_t at = 0; at <= dotted.size();) {
    const std::size_t dot = std::min(dotted.find('.', at), dotted.size());
    if (!node->is_object()) return false;
    const auto it = node->find(std::string(dotted.substr(at, dot - at)));
    if (it == node->end()) return false;
    node = &*it;
    at = dot + 1;
  }
  return node->is_boolean() && node->get<bool>();
}

// Plugins that declare a capability by themselves (a manifest's "declared_when": the fleet plugin on robots with
// runtime.r2r.enabled) join an auto-detected list. Beside a written list that does not name them they run without
// being advertised: what a robot advertises is what its file declares (§9.5), and one that wants to offer it lists it.
void add_declared_when(const RobotConfig& config, const ProviderLookup& lookup, CapabilityPlan& plan) {
  if (!lookup.declared_when) return;
  for (const auto& [name, key] : lookup.declared_when()) {
    if (!config_flag_set(config.doc, key) || std::find(plan.names.begin(), plan.names.end(), name) != plan.names.end() ||
        std::find(plan.unadvertised.begin(), plan.unadvertised.end(), name) != plan.unadvertised.end())
      continue;
    (plan.auto_detected ? plan.names : plan.unadvertised).push_back(name);
    plan.notes.push_back("'" + name + "' " + (plan.auto_detected ? "declared" : "runs, not advertised (not listed)") + ": " +
                         key + " is true and an installed plugin declares it then");
  }
}

// A listed name that is neither §9's nor reverse-domain: a typo (refused), or, in a file of another RCAN major version
// and no near miss of a §9 name, that version's capability (true: not served, with a note).
bool other_version_capability(const RobotConfig& config, const std::string& name, const std::string& path,
                              std::vector<std::string>& notes) {
  const auto close = closest_match(name, standard_names());
  const auto major = config_detail::rcan_major_version(config.rcan_version);
  if (!close && major && *major != 1) {
    notes.push_back(path + ": '" + name + "' is no RCAN 1.3 capability (the file is written for RCAN " + config.rcan_version +
                    "): not served, not advertised");
    return true;
  }
  std::string message = "'" + name + "' is neither a standard capability (" + join(standard_names(), ", ") +
                        ") nor a reverse-domain custom name like com.acme.gripper (§9.4)";
  if (close) message += "; did you mean '" + *close + "'?";
  fail(config, path, message);
}

}  // namespace

bool is_reverse_domain_name(std::string_view name) noexcept {
  int labels = 0;
  std::size_t start = 0;
  while (start <= name.size()) {
    const auto dot = name.find('.', start);
    const auto label = name.substr(start, dot == std::string_view::npos ? std::string_view::npos : dot - start);
    if (label.empty() || label.front() < 'a' || label.front() > 'z') return false;
    for (char c : label)
      if (!((c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_' || c == '-')) return false;
    ++labels;
    if (dot == std::string_view::npos) break;
    start = dot + 1;
  }
  return labels >= 3;
}

bool has_nav_physics(const RobotConfig& config) noexcept {
  return config.wheel_circumference_m.has_value() && config.turn_time_per_deg_s.has_value();
}

CapabilityPlan plan_capabilities(const RobotConfig& config, const ProviderLookup& lookup) {
  CapabilityPlan plan;
  auto providers = [&](std::string_view name) { return lookup.providers ? lookup.providers(name) : std::vector<std::string>{}; };

  if (!config.capabilities) {
    plan.auto_detected = true;
    for (auto& name : auto_detect(config, lookup, plan.notes)) {
      if (name != "status" && providers(name).empty()) {
        const auto provider = first_party_provider(name);
        plan.notes.push_back("auto-detected '" + name + "' dropped: no installed plugin provides it (install " +
                             std::string(provider.plugin) + " from " + std::string(provider.package) + ")");
        continue;
      }
      plan.names.push_back(std::move(name));
    }
    plan.notes.push_back("capabilities auto-detected (§9.3): " + join(plan.names, ", "));
    add_declared_when(config, lookup, plan);
    return plan;
  }

  plan.names.emplace_back("status");  // the kernel always serves status (§9.3 "always"; §15.4 needs it)
  const auto& listed = *config.capabilities;
  if (std::find(listed.begin(), listed.end(), "status") == listed.end())
    plan.notes.emplace_back("'status' is always served and was added to rcan_protocol.capabilities");
  for (std::size_t i = 0; i < listed.size(); ++i) {
    const std::string& name = listed[i];
    const std::string path = "rcan_protocol.capabilities[" + std::to_string(i) + "]";
    const auto* standard = find_standard_capability(name);
    if (standard == nullptr && !is_reverse_domain_name(name) && other_version_capability(config, name, path, plan.notes))
      continue;
    if (name == kNavCapability && !has_nav_physics(config))
      fail(config, path,
           "'nav' needs physics.wheel_circumference_m and physics.turn_time_per_deg_s (§10.2); add them or remove nav");
    if (name != "status") {
      auto found = providers(name);
      if (found.empty()) {
        std::string message = "'" + name + "' is listed but no installed plugin provides it";
        if (standard != nullptr)
          message += "; the plugin that could is " + std::string(first_party_provider(name).plugin) + " (package " +
                     std::string(first_party_provider(name).package) + ")";
        else message += "; install the vendor plugin that provides it into a plugin path";
        fail(config, path, message);
      }
    }
    if (std::find(plan.names.begin(), plan.names.end(), name) != plan.names.end()) {
      if (name != "status") plan.notes.push_back("'" + name + "' is listed twice; declared once");
      continue;
    }
    plan.names.push_back(name);
  }
  add_declared_when(config, lookup, plan);
  return plan;
}

CapabilityRegistry::CapabilityRegistry(RobotIdentity identity, CapabilityPlan plan)
    : identity_(std::move(identity)), plan_(std::move(plan)) {}

std::vector<std::string> CapabilityRegistry::served() const {
  std::vector<std::string> all = plan_.names;
  all.insert(all.end(), plan_.unadvertised.begin(), plan_.unadvertised.end());
  return all;
}

bool CapabilityRegistry::declared(std::string_view name) const noexcept {
  return std::find(plan_.names.begin(), plan_.names.end(), name) != plan_.names.end();
}

sdk::Scope CapabilityRegistry::minimum_scope(std::string_view name) noexcept {
  if (const auto* standard = find_standard_capability(name)) return standard->scope;
  return Scope::Control;
}

Advertisement CapabilityRegistry::advertise(std::string_view status, std::uint16_t port) const {
  Advertisement ad;
  ad.capabilities = plan_.names;
  ad.config_view = {{"rcan_protocol", {{"capabilities", ad.capabilities}}}};

  std::vector<std::string> roles;
  for (auto role : {sdk::Role::Creator, sdk::Role::Owner, sdk::Role::Leasee, sdk::Role::User, sdk::Role::Guest})
    roles.emplace_back(sdk::role_name(role));
  ad.txt = {{"ruri", identity_.ruri},
            {"model", identity_.model},
            {"caps", join(ad.capabilities, ",")},
            {"roles", join(roles, ",")},
            // The lowest role that may command this robot, so a client knows what credential it needs.
            {"role", std::string(sdk::role_name(sdk::minimum_role(Scope::Control)))},
            {"version", std::string(kRcanVersion)},
            {"name", identity_.name},
            {"status", std::string(status)}};

  ad.discover = {
      {"ruri", identity_.ruri}, {"name", identity_.name}, {"model", identity_.model},        {"version", kRcanVersion},
      {"status", status},       {"port", port},           {"capabilities", ad.capabilities}, {"service_type", kServiceType},
      {"txt_record", ad.txt}};
  return ad;
}

}  // namespace rcand::kernel
