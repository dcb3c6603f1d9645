#include "kernel/registry/capability_registry.hpp"

#include "libs/base/string_list.hpp"
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

[[noreturn]] void fail(const config::RobotConfig& config, const std::string& path, std::string message) {
  throw yaml::ConfigError(
      {yaml::ConfigDiagnostic{yaml::ConfigDiagnostic::Severity::Error, config.mark_of(path), path, std::move(message)}});
}

// The capabilities the configured drivers imply, each driver as its manifest says ("implies": a Dynamixel bus is an
// arm's servos with physics.kinematics, a drive without), plus: any driver implementing differential_drive implies
// nav and teleop, any implementing joint_arm arm. An implication its "unless" key turns off that nothing else gives
// is named in a note beside the one that applies instead.
std::vector<std::string> implied_by_drivers(const config::RobotConfig& config, const ProviderLookup& lookup,
                                            std::vector<std::string>& notes) {
  std::vector<std::string> implied, off;
  std::vector<std::pair<std::string, DriverImplication>> read_as;  // protocol, an implication with a note
  for (const auto& driver : config.drivers) {
    const auto interface = lookup.driver_interface ? lookup.driver_interface(driver.protocol) : std::nullopt;
    if (interface == "differential_drive")
      implied.insert(implied.end(), {std::string(kNavCapability), std::string(kTeleopCapability)});
    if (interface == "joint_arm") implied.emplace_back(kArmCapability);
    for (auto& implication : lookup.driver_implies ? lookup.driver_implies(driver.protocol) : std::vector<DriverImplication>{}) {
      const bool applies = (implication.when.empty() || config.is_set(implication.when)) &&
                           (implication.unless.empty() || !config.is_set(implication.unless));
      auto& into = applies ? implied : off;
      into.insert(into.end(), implication.capabilities.begin(), implication.capabilities.end());
      if (applies && !implication.reads_as.empty()) read_as.emplace_back(driver.protocol, std::move(implication));
    }
  }
  std::erase_if(off, [&](const std::string& name) { return std::find(implied.begin(), implied.end(), name) != implied.end(); });
  for (const auto& [protocol, implication] : read_as)
    if (!off.empty())
      add_unique(notes, protocol + " drivers" + (implication.when.empty() ? "" : " with " + implication.when) + " read as " +
                            implication.reads_as + ": " + join(implication.capabilities, ", ") + ", not " + join(off, " or ") +
                            " (list rcan_protocol.capabilities for a robot that also has those)");
  return implied;
}

// §9.3: status always; what the drivers imply (nav only with the §10.2 physics); vision with a camera, chat with an
// agent. Standard capabilities in the table's order, then custom ones as implied.
std::vector<std::string> auto_detect(const config::RobotConfig& config, const ProviderLookup& lookup,
                                     std::vector<std::string>& notes) {
  auto implied = implied_by_drivers(config, lookup, notes);
  if (config.has_camera) implied.emplace_back(kVisionCapability);
  if (config.has_agent) implied.emplace_back(kChatCapability);
  const auto is_implied = [&](std::string_view name) { return std::find(implied.begin(), implied.end(), name) != implied.end(); };
  if (is_implied(kNavCapability) && !has_nav_physics(config)) {
    std::erase(implied, std::string(kNavCapability));
    notes.emplace_back("nav not declared: physics.wheel_circumference_m and physics.turn_time_per_deg_s are required (§10.2)");
  }
  std::vector<std::string> found{std::string(kStatusCapability)};
  for (const auto& cap : standard_capabilities())
    if (is_implied(cap.name)) add_unique(found, std::string(cap.name));
  for (auto& name : implied)
    if (find_standard_capability(name) == nullptr) add_unique(found, std::move(name));
  return found;
}

// Plugins that declare a capability by themselves (a manifest's "declared_when": the fleet plugin on robots with
// runtime.r2r.enabled) join an auto-detected list. Beside a written list that does not name them they run without
// being advertised: what a robot advertises is what its file declares (§9.5), and one that wants to offer it lists it.
void add_declared_when(const config::RobotConfig& config, const ProviderLookup& lookup, CapabilityPlan& plan) {
  if (!lookup.declared_when) return;
  for (const auto& [name, key] : lookup.declared_when()) {
    if (!config.is_true(key) || std::find(plan.names.begin(), plan.names.end(), name) != plan.names.end() ||
        std::find(plan.unadvertised.begin(), plan.unadvertised.end(), name) != plan.unadvertised.end())
      continue;
    (plan.auto_detected ? plan.names : plan.unadvertised).push_back(name);
    plan.notes.push_back("'" + name + "' " + (plan.auto_detected ? "declared" : "runs, not advertised (not listed)") + ": " +
                         key + " is true and an installed plugin declares it then");
  }
}

// A listed name that is neither §9's nor reverse-domain: a typo (refused), or, in a file of another RCAN major version
// and no near miss of a §9 name, that version's capability (true: not served, with a note).
bool other_version_capability(const config::RobotConfig& config, const std::string& name, const std::string& path,
                              std::vector<std::string>& notes) {
  const auto close = closest_match(name, standard_names());
  const auto major = config::detail::rcan_major_version(config.rcan_version);
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

bool has_nav_physics(const config::RobotConfig& config) noexcept {
  return config.wheel_circumference_m.has_value() && config.turn_time_per_deg_s.has_value();
}

CapabilityPlan plan_capabilities(const config::RobotConfig& config, const ProviderLookup& lookup) {
  CapabilityPlan plan;
  auto providers = [&](std::string_view name) { return lookup.providers ? lookup.providers(name) : std::vector<std::string>{}; };

  if (!config.capabilities) {
    plan.auto_detected = true;
    for (auto& name : auto_detect(config, lookup, plan.notes)) {
      if (name != "status" && providers(name).empty()) {
        const auto provider = first_party_provider(name);
        plan.notes.push_back("auto-detected '" + name + "' dropped: no installed plugin provides it (install " +
                             (provider.plugin.empty() ? std::string("the plugin that provides it")
                                                      : std::string(provider.plugin) + " from " + std::string(provider.package)) +
                             ")");
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
