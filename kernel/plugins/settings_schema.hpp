// A plugin instance's settings: the rule is the SDK contract's (rcand/sdk/contract/settings.hpp), the very functions
// the fake host calls, so the two cannot disagree. The kernel adds what only it knows: where the key at fault is
// written in the config file.
#pragma once

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

#include "libs/config/robot_config.hpp"
#include "rcand/sdk/contract/settings.hpp"

namespace rcand::kernel {

// "watchdog_ms: expected integer >= 1, found -3"; key() and problem() apart.
using ConfigSchemaError = sdk::contract::SettingsError;

// A manifest's "config" schema, checked at load; `field_prefix` starts field names ("config.").
inline void check_config_schema(const nlohmann::json& schema, const std::string& field_prefix = {}) {
  sdk::contract::check_settings_schema(schema, field_prefix);
}

// The settings with defaults filled in, or ConfigSchemaError. `driver_entry`: a drivers[] entry, whose RCAN fields
// (id, protocol, port, address, baud_rate, channels) are kept beside the plugin's own settings. Unknown keys that
// are no near miss go to `ignored` (null: refused, as rcand --strict does).
inline nlohmann::json apply_config_schema(const nlohmann::json& schema, const nlohmann::json& settings, bool driver_entry,
                                          std::vector<std::string>* ignored = nullptr) {
  return driver_entry ? sdk::contract::apply_settings(schema, settings, sdk::contract::kDriverEntryKeys, ignored)
                      : sdk::contract::apply_settings(schema, settings, {}, ignored);
}

// apply_config_schema() for the instance configured at `path` ("drivers[0]", "runtime.capabilities.teleop") by
// plugin `plugin_id`: a refusal is a ConfigError at the file:line:column of the key at fault (of the block, when the
// key is not written there), like every other config error; an ignored key is a warning logged at its position, or
// with --strict (default_load_options) an error like the loader's own warnings.
nlohmann::json plugin_settings(const RobotConfig& config, const std::string& plugin_id, const nlohmann::json& schema,
                               const nlohmann::json& settings, bool driver_entry, const std::string& path);

}  // namespace rcand::kernel
