// The plugin settings rule the kernel and the SDK's fake host share. A manifest's "config" is a settings schema - a
// subset of JSON Schema (2020-12) - checked when the plugin loads; each instance's settings (a drivers[] entry, a
// runtime.capabilities.<name> block) are validated against it: every problem named with the path of the setting at
// fault ("channels.left.in1", "servos[2].id"), defaults filled in, the hardware the settings name collected as claims
// (claims.hpp) so the host can refuse two settings that name the same pin. Both hosts call these functions and nothing
// else, so a settings test that passes on the fake host gives the robot's answer (tests/unit/contract runs the same
// cases through both). Pure and header-only.
//
// The schema: either the older flat map {setting: entry} or an object schema {"type": "object", "properties": {...}}.
// Keywords: type (one or a list), description, title, default, examples, enum, const, minimum, maximum,
// exclusiveMinimum, exclusiveMaximum, minLength, maxLength, pattern, properties, required (a list on the object, or
// true on a property), additionalProperties, dependentRequired, items, minItems, maxItems, uniqueItems, contains,
// oneOf, anyOf, allOf, if/then/else, $ref to the top-level $defs, errorMessage (the message when a pattern, const,
// contains or oneOf fails, or on a then/else), deprecated, x-unit; and two of rcand's own: x-claim (claims.hpp) and
// x-rules (settings_rule.hpp). Where rcand differs from JSON Schema: an object schema that lists its properties takes
// no others unless additionalProperties says so; the top level takes what the host rule says (SettingsRules). String
// values are never echoed in an error (they may be secrets), except for enum, const and pattern settings whose name
// does not look like a secret.
#pragma once

#include <nlohmann/json.hpp>

#include <array>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "claims.hpp"
#include "settings_rule.hpp"
#include "settings_schema_check.hpp"
#include "settings_validate.hpp"

namespace rcand::sdk::contract {

// The RCAN drivers[] fields (docs/protocol.md §10.1) a driver entry carries beside its plugin's own settings. `id` and
// `protocol` are always the host's; the others are kept as written for a plugin whose manifest has the older flat
// "config" map, and are settings like any other (declared, or refused as unknown) for one with an object schema.
inline constexpr std::array<std::string_view, 6> kDriverEntryKeys{"id", "protocol", "port", "address", "baud_rate", "channels"};

// Whether `config` is an object schema ({"type": "object", "properties": ...}) rather than the flat map.
inline bool is_object_schema(const nlohmann::json& config) {
  return config.is_object() && config.contains("type") && config["type"].is_string();
}

// The schema settings are validated against: `config` itself, or the flat map wrapped as an object schema.
inline nlohmann::json settings_root(const nlohmann::json& config) {
  if (is_object_schema(config)) return config;
  return {{"type", "object"}, {"properties", config.is_object() ? config : nlohmann::json::object()}};
}

// The manifest check: throws SettingsError naming the field ("config.watchdog_ms.type: required (...)") when a
// "config" schema is malformed. `field_prefix` starts every field name ("config." for a manifest).
inline void check_settings_schema(const nlohmann::json& schema, const std::string& field_prefix = {}) {
  const std::string where =
      field_prefix.empty() ? "config" : field_prefix.substr(0, field_prefix.size() - (field_prefix.back() == '.'));
  if (!schema.is_object()) throw SettingsError(where, std::string("expected object, found ") + schema.type_name());
  if (is_object_schema(schema)) {
    if (schema["type"] != "object") throw SettingsError(where + ".type", "a settings schema is an object: expected \"object\"");
    settings_detail::SchemaChecker(schema).node(schema, where, true);
    return;
  }
  const nlohmann::json root = settings_root(schema);
  const settings_detail::SchemaChecker checker(root);
  for (const auto& [key, entry] : schema.items()) {
    if (key.empty()) throw SettingsError(where, "a setting name is empty");
    if (!entry.is_object()) throw SettingsError(field_prefix + key, std::string("expected object, found ") + entry.type_name());
    if (!entry.contains("type"))
      throw SettingsError(field_prefix + key + ".type", "required (one of string, number, integer, boolean, array, object)");
    checker.node(entry, field_prefix + key);
  }
}

// Validates an instance's settings (a mapping, or null for none) against a plugin's "config" schema (already checked)
// and returns them with defaults filled in, every problem, the keys left out and the claims. An explicit null means
// "not set".
inline SettingsResult validate_settings(const nlohmann::json& schema, const nlohmann::json& settings, SettingsRules rules = {}) {
  SettingsResult result;
  if (!settings.is_null() && !settings.is_object()) {
    result.problems.push_back({"", std::string("expected object, found ") + settings.type_name()});
    result.settings = settings;
    return result;
  }
  rules.legacy_schema = !is_object_schema(schema);
  const nlohmann::json root = settings_root(schema);
  settings_detail::Validator validator(root, rules);
  result.settings = validator.validate(root, settings.is_null() ? nlohmann::json::object() : settings, "", true);
  result.problems = std::move(validator.problems);
  result.ignored = std::move(validator.ignored);
  // Claims of the settings that passed, even when others did not: a host names every mistake at once.
  result.claims = settings_detail::resolve_claims(validator.claims, result.settings);
  return result;
}

// validate_settings() for one answer: the settings with defaults filled in, or SettingsError for the first problem.
// Keys in `also_allowed` (a driver entry's kDriverEntryKeys) are kept as kDriverEntryKeys says. A key the schema does
// not name is refused when it is a near miss of one it does (a typo: the did-you-mean names it); any other unknown
// key is left out of the result and appended to `ignored`, for the host to warn about - or refused too when `ignored`
// is null (strict, and always for drivers).
inline nlohmann::json apply_settings(const nlohmann::json& schema, const nlohmann::json& settings,
                                     std::span<const std::string_view> also_allowed = {},
                                     std::vector<std::string>* ignored = nullptr) {
  check_settings_schema(schema);
  auto result = validate_settings(schema, settings,
                                  SettingsRules{also_allowed, ignored ? UnknownKeys::WarnUnlessNearMiss : UnknownKeys::Refuse});
  if (!result.problems.empty()) throw SettingsError(result.problems.front().key, result.problems.front().problem);
  if (ignored) ignored->insert(ignored->end(), result.ignored.begin(), result.ignored.end());
  return std::move(result.settings);
}

// The settings schema of what a manifest provides (`kind` "driver" or "capability", `name` its protocol or name):
// the provides item's own "config", else the manifest's, else none (an empty schema: the instance takes no settings).
inline nlohmann::json item_settings_schema(const nlohmann::json& manifest, std::string_view kind, std::string_view name) {
  if (!manifest.is_object()) return nlohmann::json::object();
  if (const auto provides = manifest.find("provides"); provides != manifest.end() && provides->is_array())
    for (const auto& item : *provides)
      if (item.is_object() && item.value("kind", "") == kind && item.value("name", "") == name && item.contains("config"))
        return item["config"];
  return manifest.value("config", nlohmann::json::object());
}

}  // namespace rcand::sdk::contract
