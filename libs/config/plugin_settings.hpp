// A plugin instance's settings: the rule is the SDK contract's (rcand/sdk/contract/settings.hpp), the very functions
// the fake host calls, so the two cannot disagree. The kernel adds what only it knows: where each key at fault is
// written in the config file.
#pragma once

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

#include "libs/config/robot_config.hpp"
#include "rcand/sdk/contract/isolation.hpp"
#include "rcand/sdk/contract/settings.hpp"

namespace rcand::config {

// "watchdog_ms: expected integer >= 1, found -3"; key() and problem() apart.
using ConfigSchemaError = sdk::contract::SettingsError;

// The settings with defaults filled in, or ConfigSchemaError for the first problem. `driver_entry`: a drivers[] entry
// (its id and protocol kept; port, address, baud_rate, channels too for a flat "config" map). Unknown keys that are no
// near miss go to `ignored` (null: refused, as rcand --strict does, and as every driver entry is).
inline nlohmann::json apply_config_schema(const nlohmann::json& schema, const nlohmann::json& settings, bool driver_entry,
                                          std::vector<std::string>* ignored = nullptr) {
  return driver_entry ? sdk::contract::apply_settings(schema, settings, sdk::contract::kDriverEntryKeys, nullptr)
                      : sdk::contract::apply_settings(schema, settings, {}, ignored);
}

// The settings of the instance configured at `path` ("drivers[0]", "runtime.capabilities.teleop", or a block a
// plugin reads: "camera") by plugin `plugin_id`, through the contract: every refusal is a ConfigError diagnostic at
// the file:line:column of the key at fault (of the block, when the key is not written there). A key the schema does
// not name is an error in a driver entry (a misspelt pin moves the wrong motor); elsewhere a near miss is an error and
// any other a warning logged at its position, or an error with --strict. `claims`, if given, receives what the
// settings name (claims.hpp).
nlohmann::json plugin_settings(const config::RobotConfig& config, const std::string& plugin_id, const nlohmann::json& schema,
                               const nlohmann::json& settings, bool driver_entry, const std::string& path,
                               std::vector<sdk::contract::Claim>* claims = nullptr);

}  // namespace rcand::config
