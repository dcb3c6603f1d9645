#include "kernel/plugins/settings_schema.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <string_view>
#include <vector>

namespace rcand::kernel {
namespace {

using nlohmann::json;

constexpr std::array<std::string_view, 6> kTypes{"string", "number", "integer", "boolean", "array", "object"};
constexpr std::array<std::string_view, 7> kEntryKeys{"type", "default", "required", "minimum", "maximum", "enum", "description"};

bool type_matches(std::string_view type, const json& value) {
  if (type == "string") return value.is_string();
  if (type == "integer") return value.is_number_integer();
  if (type == "number") return value.is_number();
  if (type == "boolean") return value.is_boolean();
  if (type == "array") return value.is_array();
  if (type == "object") return value.is_object();
  return false;
}

bool looks_secret(std::string_view field) {
  std::string lower(field);
  std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  for (std::string_view word : {"secret", "token", "password", "key", "credential", "auth"})
    if (lower.find(word) != std::string::npos) return true;
  return false;
}

// Config values may be secrets (API keys): strings are shown only for enum settings whose name does not look
// like a secret; otherwise described by type. Everything else is shown, shortened.
std::string describe(const json& value, std::string_view field = {}, bool show_strings = false) {
  if (value.is_string() && (!show_strings || looks_secret(field))) return "a string";
  std::string text = value.dump();
  if (text.size() > 40) text = text.substr(0, 37) + "...";
  return value.is_structured() ? std::string(value.type_name()) + " " + text : text;
}

std::string expectation(std::string_view type, const json& entry) {
  std::string text(type);
  const auto min = entry.find("minimum");
  const auto max = entry.find("maximum");
  if (min != entry.end() && max != entry.end()) text += " in [" + min->dump() + ", " + max->dump() + "]";
  else if (min != entry.end()) text += " >= " + min->dump();
  else if (max != entry.end()) text += " <= " + max->dump();
  return text;
}

std::string one_of(const json& choices) {
  std::string text;
  for (const auto& choice : choices) text += (text.empty() ? "" : ", ") + choice.dump();
  return text;
}

std::size_t edit_distance(std::string_view a, std::string_view b) {
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

// Checks one value against one (already checked) schema entry; `field` names it in the error.
void check_value(const std::string& field, const json& entry, const json& value) {
  const std::string type = entry.at("type").get<std::string>();
  if (!type_matches(type, value))
    throw ConfigSchemaError(field + ": expected " + expectation(type, entry) + ", found " +
                            (value.is_string() ? std::string("string") : std::string(value.type_name())));
  if (value.is_number()) {
    const double number = value.get<double>();
    const auto min = entry.find("minimum");
    const auto max = entry.find("maximum");
    if ((min != entry.end() && number < min->get<double>()) || (max != entry.end() && number > max->get<double>()))
      throw ConfigSchemaError(field + ": expected " + expectation(type, entry) + ", found " + describe(value));
  }
  if (const auto choices = entry.find("enum"); choices != entry.end()) {
    if (std::find(choices->begin(), choices->end(), value) == choices->end())
      throw ConfigSchemaError(field + ": expected one of " + one_of(*choices) + ", found " + describe(value, field, true));
  }
}

}  // namespace

void check_config_schema(const json& schema, const std::string& prefix) {
  const std::string where = prefix.empty() ? "config" : prefix.substr(0, prefix.size() - (prefix.back() == '.'));
  if (!schema.is_object()) throw ConfigSchemaError(where + ": expected object, found " + schema.type_name());
  for (const auto& [key, entry] : schema.items()) {
    const std::string field = prefix + key;
    if (key.empty()) throw ConfigSchemaError(where + ": a setting name is empty");
    if (!entry.is_object()) throw ConfigSchemaError(field + ": expected object, found " + entry.type_name());
    for (const auto& [attribute, unused] : entry.items()) {
      (void)unused;
      if (std::find(kEntryKeys.begin(), kEntryKeys.end(), attribute) == kEntryKeys.end())
        throw ConfigSchemaError(field + "." + attribute +
                                ": unknown key; expected one of type, default, required, minimum, maximum, enum, "
                                "description" +
                                closest_hint(attribute, kEntryKeys));
    }
    const auto type = entry.find("type");
    if (type == entry.end())
      throw ConfigSchemaError(field + ".type: required (one of string, number, integer, boolean, array, object)");
    if (!type->is_string() || std::find(kTypes.begin(), kTypes.end(), type->get<std::string>()) == kTypes.end())
      throw ConfigSchemaError(field + ".type: expected one of string, number, integer, boolean, array, object, found " +
                              type->dump());
    const std::string type_name = type->get<std::string>();
    const bool numeric = type_name == "number" || type_name == "integer";
    for (const char* bound : {"minimum", "maximum"}) {
      const auto it = entry.find(bound);
      if (it == entry.end()) continue;
      if (!numeric) throw ConfigSchemaError(field + "." + bound + ": only allowed for number and integer settings");
      if (!it->is_number()) throw ConfigSchemaError(field + "." + bound + ": expected number, found " + it->type_name());
    }
    if (entry.contains("minimum") && entry.contains("maximum") && entry["minimum"].get<double>() > entry["maximum"].get<double>())
      throw ConfigSchemaError(field + ".minimum: greater than maximum");
    if (const auto required = entry.find("required"); required != entry.end() && !required->is_boolean())
      throw ConfigSchemaError(field + ".required: expected boolean, found " + required->type_name());
    if (const auto text = entry.find("description"); text != entry.end() && !text->is_string())
      throw ConfigSchemaError(field + ".description: expected string, found " + text->type_name());
    if (const auto choices = entry.find("enum"); choices != entry.end()) {
      if (!choices->is_array() || choices->empty()) throw ConfigSchemaError(field + ".enum: expected a non-empty array");
      for (const auto& choice : *choices)
        if (!type_matches(type_name, choice))
          throw ConfigSchemaError(field + ".enum: " + choice.dump() + " is not a " + type_name);
    }
    if (const auto fallback = entry.find("default"); fallback != entry.end()) check_value(field + ".default", entry, *fallback);
  }
}

json apply_config_schema(const json& schema, const json& settings, bool allow_unknown) {
  check_config_schema(schema);
  if (!settings.is_null() && !settings.is_object())
    throw ConfigSchemaError(std::string("settings: expected object, found ") + settings.type_name());
  json result = settings.is_null() ? json::object() : settings;
  for (const auto& [key, entry] : schema.items()) {
    const auto it = result.find(key);
    if (it == result.end() || it->is_null()) {
      if (const auto fallback = entry.find("default"); fallback != entry.end()) result[key] = *fallback;
      else if (entry.value("required", false))
        throw ConfigSchemaError(key + ": required (" + expectation(entry["type"].get<std::string>(), entry) +
                                (entry.contains("description") ? ": " + entry["description"].get<std::string>() : "") + ")");
      else if (it != result.end()) result.erase(it);  // an explicit null means "not set"
      continue;
    }
    check_value(key, entry, *it);
  }
  if (!allow_unknown) {
    std::vector<std::string> allowed;
    for (const auto& [key, entry] : schema.items()) allowed.push_back(key);
    for (const auto& [key, value] : result.items()) {
      (void)value;
      if (schema.contains(key)) continue;
      std::string list;
      for (const auto& name : allowed) list += (list.empty() ? "" : ", ") + name;
      throw ConfigSchemaError(key + ": unknown key; " +
                              (allowed.empty() ? std::string("this plugin takes no settings")
                                               : "expected one of: " + list + closest_hint(key, allowed)));
    }
  }
  return result;
}

}  // namespace rcand::kernel
