// The plugin settings rule the kernel and the SDK's fake host share: a manifest's "config" schema is checked when the
// plugin loads, and each instance's settings are validated against it (types, minimum, maximum, enum, required),
// defaults filled in, and unknown keys either refused (a near miss of an allowed key: a typo, with a did-you-mean)
// or dropped and named for a warning (any other: a key another runtime's config carries). Both hosts call these
// functions and nothing else, so a settings test that passes on the fake host gives the robot's answer
// (tests/unit/contract runs the same cases through both). Pure and header-only.
//
// A schema entry: {"type": "string"|"number"|"integer"|"boolean"|"array"|"object", "default", "required",
// "minimum", "maximum", "enum", "description"}. String values are never echoed in an error (they may be secrets),
// except for an enum setting whose name does not look like a secret.
#pragma once

#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cctype>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace rcand::sdk::contract {

// A setting refused, or a manifest's "config" schema that is malformed.
class SettingsError : public std::runtime_error {
 public:
  SettingsError(std::string key, std::string problem)
      : std::runtime_error((key.empty() ? std::string("settings") : key) + ": " + problem),
        key_(std::move(key)),
        problem_(std::move(problem)) {}
  // The setting at fault ("watchdog_ms"), or the manifest field ("config.watchdog_ms.type"); "" when the settings as
  // a whole are wrong (not a mapping).
  const std::string& key() const noexcept { return key_; }
  // What is wrong with it: "expected integer >= 1, found 0". what() is "<key>: <problem>".
  const std::string& problem() const noexcept { return problem_; }

 private:
  std::string key_, problem_;
};

// The RCAN drivers[] fields (docs/protocol.md §10.1) a driver entry carries beside its plugin's own settings: they
// are handed to the plugin as written and never refused as unknown.
inline constexpr std::array<std::string_view, 6> kDriverEntryKeys{"id", "protocol", "port", "address", "baud_rate", "channels"};

namespace settings_detail {

using nlohmann::json;

inline constexpr std::array<std::string_view, 6> kTypes{"string", "number", "integer", "boolean", "array", "object"};
inline constexpr std::array<std::string_view, 7> kEntryKeys{"type",    "default", "required",   "minimum",
                                                            "maximum", "enum",    "description"};

inline bool type_matches(std::string_view type, const json& value) {
  if (type == "string") return value.is_string();
  if (type == "integer") return value.is_number_integer();
  if (type == "number") return value.is_number();
  if (type == "boolean") return value.is_boolean();
  if (type == "array") return value.is_array();
  if (type == "object") return value.is_object();
  return false;
}

inline bool looks_secret(std::string_view field) {
  std::string lower(field);
  std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  for (std::string_view word : {"secret", "token", "password", "key", "credential", "auth"})
    if (lower.find(word) != std::string::npos) return true;
  return false;
}

// Strings are shown only for enum settings whose name does not look like a secret; everything else is shown, shortened.
inline std::string describe(const json& value, std::string_view field = {}, bool show_strings = false) {
  if (value.is_string() && (!show_strings || looks_secret(field))) return "a string";
  std::string text = value.dump();
  if (text.size() > 40) text = text.substr(0, 37) + "...";
  return value.is_structured() ? std::string(value.type_name()) + " " + text : text;
}

inline std::string expectation(std::string_view type, const json& entry) {
  std::string text(type);
  const auto min = entry.find("minimum");
  const auto max = entry.find("maximum");
  if (min != entry.end() && max != entry.end()) text += " in [" + min->dump() + ", " + max->dump() + "]";
  else if (min != entry.end()) text += " >= " + min->dump();
  else if (max != entry.end()) text += " <= " + max->dump();
  return text;
}

inline std::string joined(const std::vector<std::string>& names, std::string_view separator = ", ") {
  std::string text;
  for (const auto& name : names) text += (text.empty() ? "" : std::string(separator)) + name;
  return text;
}

inline std::size_t edit_distance(std::string_view a, std::string_view b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diagonal = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t above = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = above;
    }
  }
  return row[b.size()];
}

// "; did you mean 'x'?" when some allowed key is close enough to be the intended one.
template <class Keys> std::string closest_hint(std::string_view key, const Keys& allowed) {
  std::string best;
  std::size_t best_distance = std::max<std::size_t>(2, key.size() / 3) + 1;
  for (const auto& candidate : allowed) {
    const std::string_view c(candidate);
    // A truncated or extended name ("watchdog" for "watchdog_ms") counts as close, whatever its length.
    const bool affix = key.size() >= 3 && c.size() >= 3 && (c.starts_with(key) || key.starts_with(c));
    const std::size_t d = affix ? 1 : edit_distance(key, c);
    if (d < best_distance) best_distance = d, best = std::string(c);
  }
  return best.empty() ? std::string() : "; did you mean '" + best + "'?";
}

// One value against one (already checked) schema entry; `field` names it in the error.
inline void check_value(const std::string& field, const json& entry, const json& value) {
  const std::string type = entry.at("type").get<std::string>();
  if (!type_matches(type, value))
    throw SettingsError(field, "expected " + expectation(type, entry) + ", found " +
                                   (value.is_string() ? std::string("string") : std::string(value.type_name())));
  if (value.is_number()) {
    const double number = value.get<double>();
    const auto min = entry.find("minimum");
    const auto max = entry.find("maximum");
    if ((min != entry.end() && number < min->get<double>()) || (max != entry.end() && number > max->get<double>()))
      throw SettingsError(field, "expected " + expectation(type, entry) + ", found " + describe(value));
  }
  if (const auto choices = entry.find("enum"); choices != entry.end()) {
    if (std::find(choices->begin(), choices->end(), value) != choices->end()) return;
    std::vector<std::string> listed;
    for (const auto& choice : *choices) listed.push_back(choice.dump());
    throw SettingsError(field, "expected one of " + joined(listed) + ", found " + describe(value, field, true));
  }
}

// The attributes of one schema entry: known names, a known type, numeric bounds on numbers only, and so on.
inline void check_entry(const std::string& field, const json& entry) {
  if (!entry.is_object()) throw SettingsError(field, std::string("expected object, found ") + entry.type_name());
  for (const auto& [attribute, unused] : entry.items()) {
    (void)unused;
    if (std::find(kEntryKeys.begin(), kEntryKeys.end(), attribute) == kEntryKeys.end())
      throw SettingsError(field + "." + attribute,
                          "unknown key; expected one of type, default, required, minimum, maximum, enum, description" +
                              closest_hint(attribute, kEntryKeys));
  }
  const auto type = entry.find("type");
  if (type == entry.end())
    throw SettingsError(field + ".type", "required (one of string, number, integer, boolean, array, object)");
  if (!type->is_string() || std::find(kTypes.begin(), kTypes.end(), type->get<std::string>()) == kTypes.end())
    throw SettingsError(field + ".type",
                        "expected one of string, number, integer, boolean, array, object, found " + type->dump());
  const std::string type_name = type->get<std::string>();
  const bool numeric = type_name == "number" || type_name == "integer";
  for (const char* bound : {"minimum", "maximum"}) {
    const auto it = entry.find(bound);
    if (it == entry.end()) continue;
    if (!numeric) throw SettingsError(field + "." + bound, "only allowed for number and integer settings");
    if (!it->is_number()) throw SettingsError(field + "." + bound, std::string("expected number, found ") + it->type_name());
  }
  if (entry.contains("minimum") && entry.contains("maximum") && entry["minimum"].get<double>() > entry["maximum"].get<double>())
    throw SettingsError(field + ".minimum", "greater than maximum");
  if (const auto required = entry.find("required"); required != entry.end() && !required->is_boolean())
    throw SettingsError(field + ".required", std::string("expected boolean, found ") + required->type_name());
  if (const auto text = entry.find("description"); text != entry.end() && !text->is_string())
    throw SettingsError(field + ".description", std::string("expected string, found ") + text->type_name());
  if (const auto choices = entry.find("enum"); choices != entry.end()) {
    if (!choices->is_array() || choices->empty()) throw SettingsError(field + ".enum", "expected a non-empty array");
    for (const auto& choice : *choices)
      if (!type_matches(type_name, choice)) throw SettingsError(field + ".enum", choice.dump() + " is not a " + type_name);
  }
  if (const auto fallback = entry.find("default"); fallback != entry.end()) check_value(field + ".default", entry, *fallback);
}

}  // namespace settings_detail

// The manifest check: throws SettingsError naming the field ("config.watchdog_ms.type: required (...)") when a
// "config" schema is malformed. `field_prefix` starts every field name ("config." for a manifest).
inline void check_settings_schema(const nlohmann::json& schema, const std::string& field_prefix = {}) {
  const std::string where =
      field_prefix.empty() ? "config" : field_prefix.substr(0, field_prefix.size() - (field_prefix.back() == '.'));
  if (!schema.is_object()) throw SettingsError(where, std::string("expected object, found ") + schema.type_name());
  for (const auto& [key, entry] : schema.items()) {
    if (key.empty()) throw SettingsError(where, "a setting name is empty");
    settings_detail::check_entry(field_prefix + key, entry);
  }
}

// Validates an instance's settings (a mapping, or null for none) against a plugin's "config" schema and returns them
// with defaults filled in; an explicit null means "not set". Keys in `also_allowed` (a driver entry's
// kDriverEntryKeys) are kept as written. A key the schema does not name is refused when it is a near miss of one it
// does (a typo: the did-you-mean names it); any other unknown key (`frequency`, `hardware_id`: a key of another
// runtime's driver) is left out of the result and appended to `ignored`, for the host to warn about - or refused
// too when `ignored` is null (strict). Throws SettingsError.
inline nlohmann::json apply_settings(const nlohmann::json& schema, const nlohmann::json& settings,
                                     std::span<const std::string_view> also_allowed = {},
                                     std::vector<std::string>* ignored = nullptr) {
  using nlohmann::json;
  check_settings_schema(schema);
  if (!settings.is_null() && !settings.is_object())
    throw SettingsError("", std::string("expected object, found ") + settings.type_name());
  json result = settings.is_null() ? json::object() : settings;
  for (const auto& [key, entry] : schema.items()) {
    const auto it = result.find(key);
    if (it == result.end() || it->is_null()) {
      if (const auto fallback = entry.find("default"); fallback != entry.end()) {
        result[key] = *fallback;
      } else if (entry.value("required", false)) {
        const std::string what = entry.contains("description") ? ": " + entry["description"].get<std::string>() : "";
        throw SettingsError(key,
                            "required (" + settings_detail::expectation(entry["type"].get<std::string>(), entry) + what + ")");
      } else if (it != result.end()) {
        result.erase(it);
      }
      continue;
    }
    settings_detail::check_value(key, entry, *it);
  }
  std::vector<std::string> allowed;
  for (const auto& [key, entry] : schema.items()) allowed.push_back(key);
  std::vector<std::string> unknown;
  for (const auto& [key, value] : result.items()) {
    (void)value;
    if (schema.contains(key) || std::find(also_allowed.begin(), also_allowed.end(), key) != also_allowed.end()) continue;
    const std::string hint = settings_detail::closest_hint(key, allowed);
    if (ignored != nullptr && hint.empty()) {
      unknown.push_back(key);
      continue;
    }
    if (allowed.empty()) throw SettingsError(key, "unknown key; this plugin takes no settings");
    throw SettingsError(key, "unknown key; expected one of: " + settings_detail::joined(allowed) + hint);
  }
  for (const auto& key : unknown) {
    result.erase(key);
    ignored->push_back(key);
  }
  return result;
}

}  // namespace rcand::sdk::contract
