// One schema table validates a plugin instance's settings (the manifest's "config"), fills in defaults,
// and rejects unknown keys naming the allowed ones (fluent-bit's config_map idea).
#pragma once

#include <nlohmann/json.hpp>

#include <stdexcept>
#include <string>

namespace rcand::kernel {

// Names the key at fault and what was expected and found: "watchdog_ms: expected integer >= 1, found -3".
// String values are never echoed (they may be secrets); only their type is.
class ConfigSchemaError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Throws ConfigSchemaError when `schema` itself is malformed (a manifest schema never is: parse_manifest
// checks it with check_config_schema). `field_prefix` is prepended to field names ("config.").
void check_config_schema(const nlohmann::json& schema, const std::string& field_prefix = {});

// Validates instance settings (an object, or null for "none") against a manifest "config" schema and
// returns them with defaults filled in. Each schema key: {"type": string|number|integer|boolean|array|object,
// "default", "required", "minimum", "maximum", "enum", "description"}. Keys not in the schema are kept when
// `allow_unknown` (driver entries also carry id/protocol), and rejected otherwise.
nlohmann::json apply_config_schema(const nlohmann::json& schema, const nlohmann::json& settings, bool allow_unknown);

}  // namespace rcand::kernel
