// A plugin's manifest: what it is and what it provides, read without opening its library.
#pragma once

#include <nlohmann/json.hpp>

#include <filesystem>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace rcand {

// What a configured driver implies when the robot's file lists no capabilities (a driver entry's "implies", §9.3 as
// the driver's manifest says it): a Dynamixel bus is an arm's servos with physics.kinematics, a drive without. The
// registry reads these; the kernel names no driver protocol.
struct DriverImplication {
  std::vector<std::string> capabilities;
  std::string when, unless;  // dotted config keys that must be set / unset (RobotConfig::is_set); empty: always
  std::string reads_as;      // for the startup note when this one applies ("an arm"); empty: no note
  bool operator==(const DriverImplication&) const = default;
};

// One entry of the manifest's "provides": a capability name or a driver protocol.
struct ProvidedItem {
  std::string kind;  // "capability" or "driver"
  std::string name;  // capability name, or driver protocol
  bool actuates = false;
  std::string interface;                   // actuating drivers only: the ActuatorDriver interface they implement
  std::string fail_safe;                   // drivers: what the hardware does by itself when rcand stops or dies ("fail_safe")
  std::vector<DriverImplication> implies;  // drivers: capabilities their presence implies ("implies")
  nlohmann::json entry;  // the "provides" entry as written: its own settings schema, the blocks it reads, needs, offers
  // What a plugin registers must equal its manifest; the fail-safe statement and the implications are the manifest's
  // alone.
  bool operator==(const ProvidedItem& o) const {
    return kind == o.kind && name == o.name && actuates == o.actuates && interface == o.interface;
  }
};

// A capability the plugin declares by itself when a config key is true (a "provides" entry's "declared_when"): the
// fleet plugin joins every robot with runtime.r2r.enabled. The registry reads these; the kernel names none of them.
struct DeclaredWhen {
  std::string capability;
  std::string config_key;  // dotted path into the robot config ("runtime.r2r.enabled")
  bool operator==(const DeclaredWhen&) const = default;
};

struct PluginManifest {
  std::filesystem::path file, library;  // library is absolute (resolved against the manifest's folder)
  std::string id, version, description;
  int abi_major = 0, abi_minor = 0;
  std::vector<ProvidedItem> provides;
  std::vector<DeclaredWhen> declared_when;                  // from "provides" entries
  std::vector<std::string> requires_;                       // actuator interfaces some enabled driver must provide
  nlohmann::json config_schema = nlohmann::json::object();  // validated: see apply_config_schema()
  std::string text;                                         // the file as read (rcand --describe keeps its key order)
};

// The settings schema of what `m` provides as `kind` "driver" or "capability" named `name`: the item's own "config",
// else the manifest's (rcand/sdk/contract/settings.hpp).
nlohmann::json settings_schema_of(const PluginManifest& m, std::string_view kind, std::string_view name);
// What `m` provides as `kind` ("driver" or "capability") named `name`; null when it provides no such item.
const ProvidedItem* find_provided(const PluginManifest& m, std::string_view kind, std::string_view name) noexcept;

// The message names the file and the field at fault: "<file>: abi.major: expected integer, found string".
class ManifestError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Validates `doc` (the parsed manifest) completely, including its "config" schema. `file` is used for the
// error messages and to resolve "library". Throws ManifestError.
PluginManifest parse_manifest(const nlohmann::json& doc, const std::filesystem::path& file);

// Reads and parses `file`. Throws ManifestError (unreadable file, bad JSON, invalid content).
PluginManifest load_manifest(const std::filesystem::path& file);

}  // namespace rcand
