// The manifest check of a settings schema: every keyword known and well-formed, every "$ref" found, every default
// and example valid against its own schema, every claim of a known kind, every rule parsed and naming the object's
// own settings. Throws SettingsError naming the manifest field ("config.properties.channels.type: ..."). Pure and
// header-only; part of the settings contract (settings.hpp).
#pragma once

#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <regex>
#include <string>
#include <string_view>

#include "settings_validate.hpp"

namespace rcand::sdk::contract::settings_detail {

inline constexpr std::array<std::string_view, 41> kKeywords{"type",
                                                            "description",
                                                            "title",
                                                            "default",
                                                            "examples",
                                                            "$comment",
                                                            "required",
                                                            "enum",
                                                            "const",
                                                            "minimum",
                                                            "maximum",
                                                            "exclusiveMinimum",
                                                            "exclusiveMaximum",
                                                            "minLength",
                                                            "maxLength",
                                                            "pattern",
                                                            "properties",
                                                            "additionalProperties",
                                                            "dependentRequired",
                                                            "items",
                                                            "minItems",
                                                            "maxItems",
                                                            "uniqueItems",
                                                            "contains",
                                                            "oneOf",
                                                            "anyOf",
                                                            "allOf",
                                                            "if",
                                                            "then",
                                                            "else",
                                                            "$ref",
                                                            "$defs",
                                                            "errorMessage",
                                                            "x-claim",
                                                            "x-rules",
                                                            "x-unit",
                                                            "deprecated",
                                                            "not",
                                                            "prefixItems",
                                                            "minProperties",
                                                            "maxProperties"};

class SchemaChecker {
 public:
  explicit SchemaChecker(const nlohmann::json& root) : root_(root) {}

  void node(const nlohmann::json& n, const std::string& field, bool is_root = false, int depth = 0) const {
    if (depth > 32) fail(field, "nested too deeply");
    if (!n.is_object()) fail(field, std::string("expected a schema object, found ") + n.type_name());
    for (const auto& [keyword, unused] : n.items()) {
      (void)unused;
      if (std::find(kKeywords.begin(), kKeywords.end(), keyword) == kKeywords.end())
        fail(field + "." + keyword,
             "unknown key; expected one of type, default, required, minimum, maximum, enum, description, "
             "properties, items, oneOf, ... (the JSON Schema subset of rcand/sdk/contract/settings.hpp)" +
                 closest_hint(keyword, kKeywords));
    }
    if (n.contains("$defs") && !is_root) fail(field + ".$defs", "only at the top of the schema");
    if (const auto ref = n.find("$ref"); ref != n.end() && reference(root_, n) == nullptr)
      fail(field + ".$ref", "expected \"#/$defs/<name>\" naming an entry of the top-level $defs, found " + ref->dump());
    check_type(n, field);
    check_words(n, field);
    check_numbers(n, field);
    check_children(n, field, depth);
    check_claim(n, field);
    check_rules(n, field);
    check_values(n, field, is_root);
  }

 private:
  [[noreturn]] static void fail(const std::string& field, const std::string& what) { throw SettingsError(field, what); }

  static void check_type(const nlohmann::json& n, const std::string& field) {
    const auto type = n.find("type");
    if (type == n.end()) return;
    const auto known = [](const nlohmann::json& t) {
      return t.is_string() && std::find(kTypes.begin(), kTypes.end(), t.get<std::string>()) != kTypes.end();
    };
    if (type->is_array() && !type->empty() && std::all_of(type->begin(), type->end(), known)) return;
    if (known(*type)) return;
    fail(field + ".type",
         "expected one of string, number, integer, boolean, array, object (or a list of them), found " + type->dump());
  }

  static void check_words(const nlohmann::json& n, const std::string& field) {
    for (const char* key : {"description", "title", "$comment", "errorMessage", "pattern", "x-unit"})
      if (const auto it = n.find(key); it != n.end() && !it->is_string())
        fail(field + "." + key, std::string("expected string, found ") + it->type_name());
    if (const auto pattern = n.find("pattern"); pattern != n.end()) try {
        (void)std::regex(pattern->get<std::string>(), std::regex::ECMAScript);
      } catch (const std::regex_error&) {
        fail(field + ".pattern", "not a valid regular expression");
      }
    if (const auto required = n.find("required"); required != n.end()) {
      const bool names =
          required->is_array() && std::all_of(required->begin(), required->end(), [](const auto& r) { return r.is_string(); });
      if (!required->is_boolean() && !names)
        fail(field + ".required",
             std::string("expected a list of property names (or true on a property), found ") + required->type_name());
    }
    for (const char* key : {"uniqueItems", "deprecated"})
      if (const auto it = n.find(key); it != n.end() && !it->is_boolean())
        fail(field + "." + key, std::string("expected boolean, found ") + it->type_name());
    if (const auto choices = n.find("enum"); choices != n.end() && (!choices->is_array() || choices->empty()))
      fail(field + ".enum", "expected a non-empty array");
  }

  static void check_numbers(const nlohmann::json& n, const std::string& field) {
    const auto types = types_of(n);
    const bool numeric =
        types.empty() || std::any_of(types.begin(), types.end(), [](const auto& t) { return t == "number" || t == "integer"; });
    for (const char* bound : {"minimum", "maximum", "exclusiveMinimum", "exclusiveMaximum"}) {
      const auto it = n.find(bound);
      if (it == n.end()) continue;
      if (!numeric) fail(field + "." + bound, "only allowed for number and integer settings");
      if (!it->is_number()) fail(field + "." + bound, std::string("expected number, found ") + it->type_name());
    }
    if (n.contains("minimum") && n.contains("maximum") && n["minimum"].get<double>() > n["maximum"].get<double>())
      fail(field + ".minimum", "greater than maximum");
    for (const char* count : {"minLength", "maxLength", "minItems", "maxItems", "minProperties", "maxProperties"})
      if (const auto it = n.find(count);
          it != n.end() && !(it->is_number_unsigned() || (it->is_number_integer() && it->get<long long>() >= 0)))
        fail(field + "." + count, "expected a non-negative integer, found " + it->dump());
  }

  void check_children(const nlohmann::json& n, const std::string& field, int depth) const {
    if (const auto defs = n.find("$defs"); defs != n.end()) {
      if (!defs->is_object()) fail(field + ".$defs", "expected object");
      for (const auto& [name, def] : defs->items()) node(def, field + ".$defs." + name, false, depth + 1);
    }
    if (const auto properties = n.find("properties"); properties != n.end()) {
      if (!properties->is_object()) fail(field + ".properties", std::string("expected object, found ") + properties->type_name());
      for (const auto& [name, property] : properties->items()) {
        if (name.empty()) fail(field + ".properties", "a setting name is empty");
        node(property, field + ".properties." + name, false, depth + 1);
      }
    }
    if (const auto extra = n.find("additionalProperties"); extra != n.end() && !extra->is_boolean())
      node(*extra, field + ".additionalProperties", false, depth + 1);
    for (const char* key : {"items", "contains", "if", "then", "else", "not"})
      if (const auto it = n.find(key); it != n.end()) node(*it, field + "." + key, false, depth + 1);
    if ((n.contains("then") || n.contains("else")) && !n.contains("if")) fail(field + ".then", "needs \"if\"");
    for (const char* key : {"oneOf", "anyOf", "allOf", "prefixItems"})
      if (const auto it = n.find(key); it != n.end()) {
        if (!it->is_array() || it->empty()) fail(field + "." + key, "expected a non-empty array of schemas");
        for (std::size_t i = 0; i < it->size(); ++i)
          node((*it)[i], field + "." + key + "[" + std::to_string(i) + "]", false, depth + 1);
      }
    if (const auto dependent = n.find("dependentRequired"); dependent != n.end()) {
      if (!dependent->is_object()) fail(field + ".dependentRequired", "expected {setting: [settings it needs]}");
      for (const auto& [name, needed] : dependent->items())
        if (!needed.is_array() || !std::all_of(needed.begin(), needed.end(), [](const auto& x) { return x.is_string(); }))
          fail(field + ".dependentRequired." + name, "expected a list of setting names");
    }
  }

  static void check_claim(const nlohmann::json& n, const std::string& field) {
    const auto claim = n.find("x-claim");
    if (claim == n.end()) return;
    const std::string at = field + ".x-claim";
    if (!claim->is_object()) fail(at, "expected {resource, scope?, value?}");
    for (const auto& [key, unused] : claim->items())
      if ((void)unused, key != "resource" && key != "scope" && key != "value")
        fail(at + "." + key, "unknown key; expected resource, scope, value");
    const auto* kind = claim_detail::find_kind(claim->value("resource", std::string()));
    if (kind == nullptr) {
      std::string known;
      for (const auto& [name, what] : claim_kinds()) known += (known.empty() ? "" : ", ") + name;
      fail(at + ".resource", "expected one of " + known + ", found " + claim->value("resource", json()).dump());
    }
    const json scope = claim->value("scope", json::array());
    if (!scope.is_array() || scope.size() != kind->scope.size())
      fail(at + ".scope", "a " + std::string(kind->name) + " claim names " + std::to_string(kind->scope.size()) +
                              " setting(s) saying where (\"/chip\" from the top, \"chip\" inside the claimed object)");
    for (const auto& item : scope)
      if (!item.is_string() && !(item.is_object() && item.contains("pointer") && item["pointer"].is_string()))
        fail(at + ".scope", "expected \"/setting\", \"setting\" or {pointer, default}, found " + item.dump());
    if (const auto value = claim->find("value"); value != claim->end() && !value->is_string())
      fail(at + ".value", "expected the name of the property that holds the claimed value");
  }

  static void check_rules(const nlohmann::json& n, const std::string& field) {
    const auto rules = n.find("x-rules");
    if (rules == n.end()) return;
    if (!rules->is_array()) fail(field + ".x-rules", "expected [{rule, message, at?}]");
    const auto properties = n.value("properties", json::object());
    for (std::size_t i = 0; i < rules->size(); ++i) {
      const std::string at = field + ".x-rules[" + std::to_string(i) + "]";
      const json& rule = (*rules)[i];
      if (!rule.is_object() || !rule.contains("rule") || !rule["rule"].is_string() || !rule.contains("message") ||
          !rule["message"].is_string())
        fail(at, "expected {\"rule\": \"a < b\", \"message\": \"...\"}");
      try {
        const SettingsRule parsed(rule["rule"].get<std::string>());
        for (const auto& name : parsed.names())
          if (!properties.contains(name)) fail(at + ".rule", "'" + name + "' is not a property of this object");
      } catch (const RuleSyntaxError& e) {
        fail(at + ".rule", e.what());
      }
      if (const auto target = rule.find("at");
          target != rule.end() && (!target->is_string() || !properties.contains(target->get<std::string>())))
        fail(at + ".at", "expected a property of this object");
    }
  }

  // Defaults and examples must pass the very validation the settings get; a top-level example is a whole instance
  // block and may carry a driver entry's id and protocol.
  void check_values(const nlohmann::json& n, const std::string& field, bool is_root) const {
    if (const auto choices = n.find("enum"); choices != n.end()) {
      const auto types = types_of(n);
      for (const auto& choice : *choices)
        if (!types.empty() && std::none_of(types.begin(), types.end(), [&](const auto& t) { return type_matches(t, choice); }))
          fail(field + ".enum", choice.dump() + " is not a " + joined(types, " or "));
    }
    static constexpr std::array<std::string_view, 2> kEntry{"id", "protocol"};
    const SettingsRules rules{is_root ? std::span<const std::string_view>(kEntry) : std::span<const std::string_view>()};
    auto valid = [&](const json& value, const std::string& where) {
      Validator validator(root_, rules);
      (void)validator.validate(n, value, "", is_root);
      if (!validator.problems.empty())
        fail(where, (validator.problems.front().key.empty() ? "" : validator.problems.front().key + ": ") +
                        validator.problems.front().problem);
    };
    if (const auto fallback = n.find("default"); fallback != n.end()) valid(*fallback, field + ".default");
    if (const auto examples = n.find("examples"); examples != n.end()) {
      if (!examples->is_array()) fail(field + ".examples", "expected an array of values");
      for (std::size_t i = 0; i < examples->size(); ++i) valid((*examples)[i], field + ".examples[" + std::to_string(i) + "]");
    }
  }

  const nlohmann::json& root_;
};

}  // namespace rcand::sdk::contract::settings_detail
