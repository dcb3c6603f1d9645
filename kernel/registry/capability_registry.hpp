// The capability registry (§9): which capabilities this robot declares, what scope each needs, and the one
// function from which the config view, the mDNS TXT record and the DISCOVER document are all derived (§9.5).
#pragma once

#include <nlohmann/json.hpp>

#include <functional>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "kernel/registry/standard_capabilities.hpp"
#include "libs/config/robot_config.hpp"
#include "libs/manifest/manifest.hpp"
#include "rcand/sdk/scope.hpp"

namespace rcand::kernel {

inline constexpr std::string_view kRcanVersion = "1.3.0";
inline constexpr std::string_view kServiceType = "_rcan._tcp";

// §9.4: lowercase labels of [a-z0-9_-], at least three of them, each starting with a letter ("com.acme.gripper").
bool is_reverse_domain_name(std::string_view name) noexcept;
// §10.2: wheel_circumference_m and turn_time_per_deg_s are both present.
bool has_nav_physics(const config::RobotConfig& config) noexcept;

// What the registry needs to know about installed plugins while planning.
struct ProviderLookup {
  // The actuator interface a driver protocol provides ("differential_drive"), if an installed plugin provides it.
  std::function<std::optional<std::string>(std::string_view protocol)> driver_interface;
  // What the presence of a driver of this protocol implies, as its installed plugin's manifest says ("implies").
  std::function<std::vector<DriverImplication>(std::string_view protocol)> driver_implies;
  // Installed plugins that provide a capability, as "id (state)" for messages; empty when none.
  std::function<std::vector<std::string>(std::string_view capability)> providers;
  // Capabilities installed plugins declare by themselves when a config key is true (their manifests' "declared_when"):
  // {capability, dotted config key}.
  std::function<std::vector<std::pair<std::string, std::string>>()> declared_when;
};

struct CapabilityPlan {
  std::vector<std::string> names;  // what this robot declares and advertises, "status" first
  // Capabilities an installed plugin declares by itself (its manifest's "declared_when") that a written
  // rcan_protocol.capabilities does not name: their plugins run (the fleet plugin's auctions on an R2R robot), but
  // the robot advertises exactly the list it was given (§9.5).
  std::vector<std::string> unadvertised;
  bool auto_detected = false;
  std::vector<std::string> notes;  // what was decided and why (logged at startup)
};

// Explicit list: every name must be standard or reverse-domain and have an installed provider ("status" is the
// kernel's own), and nav needs the §10.2 physics fields; violations throw ConfigError with file:line:column.
// Absent list: §9.3 auto-detection as the drivers' manifests say it ("implies"), extended so any driver implementing
// differential_drive implies teleop (and nav with physics) and any implementing joint_arm arm; auto-detected
// capabilities without an installed provider are dropped with a note.
// A capability an installed plugin declares by itself when its config key is true joins an auto-detected list, and
// runs unadvertised beside a written one that does not name it.
CapabilityPlan plan_capabilities(const config::RobotConfig& config, const ProviderLookup& lookup);

struct RobotIdentity {
  std::string ruri, name, model;
};

struct Advertisement {
  std::vector<std::string> capabilities;   // the one list
  nlohmann::json config_view;              // {"rcan_protocol":{"capabilities":[...]}}
  std::map<std::string, std::string> txt;  // mDNS TXT keys (docs/protocol.md §5)
  nlohmann::json discover;                 // GET /api/discovery (docs/protocol.md §5 ruling)
};

class CapabilityRegistry {
 public:
  CapabilityRegistry(RobotIdentity identity, CapabilityPlan plan);

  bool declared(std::string_view name) const noexcept;
  const std::vector<std::string>& names() const noexcept { return plan_.names; }
  // What runs: the declared capabilities, then the unadvertised ones (CapabilityPlan::unadvertised).
  std::vector<std::string> served() const;
  const RobotIdentity& identity() const noexcept { return identity_; }
  // The scope a capability's routes need at least: its §9.2 scope, or Control for custom ones (§9.4).
  static sdk::Scope minimum_scope(std::string_view name) noexcept;

  // THE one function: every advertisement of the capability list comes from here.
  Advertisement advertise(std::string_view status, std::uint16_t port) const;

 private:
  RobotIdentity identity_;
  CapabilityPlan plan_;
};

}  // namespace rcand::kernel
