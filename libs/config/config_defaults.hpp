// What rcand makes of a valid config written for another runtime or RCAN version (docs/protocol.md §10.3): the
// values it leaves out are supplied, the names it uses for the same hardware are read as rcand's, and what rcand does
// not implement is dropped; each with a warning at the key's position, so `--strict` can refuse any of it.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "libs/config/robot_config.hpp"

namespace rcand::config {

// "Castor_RC_Car" -> "castor-rc-car": lower case, every run of other characters one '-', none at either end
// ("robot" when nothing is left).
std::string model_slug(std::string_view robot_name);

// The manufacturer a config that names none gets.
inline constexpr std::string_view kUnknownManufacturer = "unknown";

// Applies every default and reading above to `config` (extracted from a validated document) and appends a warning
// to `warnings` for each.
void apply_config_defaults(RobotConfig& config, std::vector<ConfigDiagnostic>& warnings);

}  // namespace rcand::config
