// Validation of an instance's settings against an (already checked) settings schema: the JSON Schema subset of
// settings.hpp. Collects every problem with the path of the setting at fault ("channels.left.in1", "servos[2].id"),
// fills defaults in, and records the claims (claims.hpp). Pure and header-only; part of the settings contract.
#pragma once

#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <regex>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "claims.hpp"
#include "settings_rule.hpp"

namespace rcand::sdk::contract {

// A setting refused, or a manifest's "config" schema that is malformed.
class SettingsError : public std::runtime_error {
 public:
  SettingsError(std::string key, std::string problem)
      : std::runtime_error((key.empty() ? std::string("settings") : key) + ": " + problem),
        key_(std::move(key)),
        problem_(std::move(problem)) {}
  // The setting at fault ("watchdog_ms", "channels.left.in1", "servos[2].id"), or the manifest field
  // ("config.watchdog_ms.type"); "" when the settings as a whole are wrong (not a mapping).
  const std::string& key() const noexcept { return key_; }
  // What is wrong with it: "expected integer >= 1, found 0". what() is "<key>: <problem>".
  const std::string& problem() const noexcept { return problem_; }

 private:
  std::string key_, problem_;
};

// One setting refused: SettingsError's two parts, for a host that reports them all.
struct SettingsProblem {
  std::string key, problem;
  bool operator==(const SettingsProblem&) const = default;
};

// What happens to a key at the top of the settings that the schema does not name.
enum class UnknownKeys {
  Refuse,             // an error (drivers: a setting the plugin does not take may move the wrong motor)
  WarnUnlessNearMiss  // a near miss of a setting is an error (a typo); any other is left out and named for a warning
};

struct SettingsRules {
  std::span<const std::string_view> entry_keys = {};  // kept as written at the top (a driver entry's id, protocol, ...)
  UnknownKeys unknown = UnknownKeys::Refuse;
  bool legacy_schema = false;  // a flat "config" map: every entry key is kept (older manifests could not declare them)
};

struct SettingsResult {
  nlohmann::json settings;                // defaults filled in, ignored keys left out
  std::vector<SettingsProblem> problems;  // empty: accepted
  std::vector<std::string> ignored;       // top-level keys left out (UnknownKeys::WarnUnlessNearMiss)
  std::vector<Claim> claims;              // what the settings that passed name (all of them when accepted)
};

namespace settings_detail {

using nlohmann::json;

inline constexpr std::array<std::string_view, 6> kTypes{"string", "number", "integer", "boolean", "array", "object"};

inline bool type_matches(std::string_view type, const json& value) {
  if (type == "string") return value.is_string();
  if (type == "integer") return value.is_number_integer();
  if (type == "number") return value.is_number();
  if (type == "boolean") return value.is_boolean();
  if (type == "array") return value.is_array();
  if (type == "object") return value.is_object();
  return false;
}

inline std::vector<std::string> types_of(const json& node) {
  const auto it = node.find("type");
  if (it == node.end()) return {};
  if (it->is_string()) return {it->get<std::string>()};
  std::vector<std::string> out;
  for (const auto& t : *it) out.push_back(t.get<std::string>());
  return out;
}

inline bool looks_secret(std::string_view field) {
  std::string lower(field);
  std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  for (std::string_view word : {"secret", "token", "password", "key", "credential", "auth"})
    if (lower.find(word) != std::string::npos) return true;
  return false;
}

// Strings are shown only where the caller says and the name does not look like a secret; the rest is shortened.
inline std::string describe(const json& value, std::string_view field = {}, bool show_strings = false) {
  if (value.is_string() && (!show_strings || looks_secret(field))) return "a string";
  std::string text = value.dump();
  if (text.size() > 40) text = text.substr(0, 37) + "...";
  return value.is_structured() ? std::string(value.type_name()) + " " + text : text;
}

inline std::string bounds(const json& node) {
  const auto min = node.find("minimum");
  const auto max = node.find("maximum");
  const auto xmin = node.find("exclusiveMinimum");
  const auto xmax = node.find("exclusiveMaximum");
  if (min != node.end() && max != node.end()) return " in [" + min->dump() + ", " + max->dump() + "]";
  std::string text;
  if (min != node.end()) text += " >= " + min->dump();
  if (xmin != node.end()) text += " > " + xmin->dump();
  if (max != node.end()) text += std::string(text.empty() ? "" : " and") + " <= " + max->dump();
  if (xmax != node.end()) text += std::string(text.empty() ? "" : " and") + " < " + xmax->dump();
  return text;
}

inline std::string joined(const std::vector<std::string>& names, std::string_view separator = ", ") {
  std::string text;
  for (const auto& name : names) text += (text.empty() ? "" : std::string(separator)) + name;
  return text;
}

// "integer in [0, 1023], string or object": what a node takes.
inline std::string expectation(const json& node) {
  std::vector<std::string> parts;
  for (const auto& type : types_of(node))
    parts.push_back(type + (type == "integer" || type == "number" ? bounds(node) : std::string()));
  if (parts.empty()) return "a value";
  std::string text;
  for (std::size_t i = 0; i < parts.size(); ++i) text += (i == 0 ? "" : i + 1 == parts.size() ? " or " : ", ") + parts[i];
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
    const bool affix = (key.size() >= 3 && c.size() >= 3 && (c.starts_with(key) || key.starts_with(c))) ||
                       (key.size() >= 2 && c.starts_with(key));
    const std::size_t d = affix ? 1 : edit_distance(key, c);
    if (d < best_distance) best_distance = d, best = std::string(c);
  }
  return best.empty() ? std::string() : "; did you mean '" + best + "'?";
}

inline std::string child(const std::string& path, std::string_view key) {
  return path.empty() ? std::string(key) : path + "." + std::string(key);
}

// The node "#/$defs/name" names, or nullptr.
inline const json* reference(const json& root, const json& node) {
  const auto ref = node.find("$ref");
  if (ref == node.end() || !ref->is_string()) return nullptr;
  const std::string text = ref->get<std::string>();
  constexpr std::string_view kPrefix = "#/$defs/";
  if (!text.starts_with(kPrefix)) return nullptr;
  const auto defs = root.find("$defs");
  if (defs == root.end() || !defs->is_object()) return nullptr;
  const auto target = defs->find(text.substr(kPrefix.size()));
  return target == defs->end() ? nullptr : &*target;
}

// The names an object node requires: its "required" list, and properties marked "required": true (the older form).
inline std::vector<std::string> required_of(const json& root, const json& node) {
  std::vector<std::string> names;
  if (const auto list = node.find("required"); list != node.end() && list->is_array())
    for (const auto& name : *list) names.push_back(name.get<std::string>());
  if (const auto properties = node.find("properties"); properties != node.end())
    for (const auto& [name, property] : properties->items()) {
      const json* target = reference(root, property);
      const bool marked = property.value("required", json()).is_boolean() ? property.value("required", false)
                          : target != nullptr && (*target).value("required", json()).is_boolean()
                              ? target->value("required", false)
                              : false;
      if (marked && std::find(names.begin(), names.end(), name) == names.end()) names.push_back(name);
    }
  return names;
}

// "{id, joint, min_deg?, max_deg?}": an object form, for "expected one of".
inline std::string form_summary(const json& root, const json& node) {
  if (const auto title = node.find("title"); title != node.end()) return title->get<std::string>();
  const auto properties = node.find("properties");
  if (properties == node.end()) return expectation(node);
  const auto required = required_of(root, node);
  std::vector<std::string> names;
  for (const auto& [name, unused] : properties->items()) {
    (void)unused;
    const bool needed = std::find(required.begin(), required.end(), name) != required.end();
    names.push_back(name + (needed ? "" : "?"));
  }
  return "{" + joined(names) + "}";
}

struct PendingClaim {
  const json* spec;
  json value;
  std::string path;
};

// One validation run; `root` is the whole schema (for "$ref").
class Validator {
 public:
  Validator(const json& root, const SettingsRules& rules) : root_(root), rules_(rules) {}

  std::vector<SettingsProblem> problems;
  std::vector<std::string> ignored;
  std::vector<PendingClaim> claims;

  json validate(const json& node, const json& value, const std::string& path, bool top = false) {
    const std::size_t before = problems.size();
    json result = value;
    if (const json* target = reference(root_, node)) result = validate(*target, value, path, top);
    if (problems.size() > before) return result;
    if (!check_type(node, result, path)) return result;
    check_scalar(node, result, path);
    if (result.is_object() && (top || node.contains("properties") || node.contains("additionalProperties") ||
                               node.contains("required") || node.contains("dependentRequired") || node.contains("x-rules") ||
                               node.contains("minProperties") || node.contains("maxProperties")))
      result = validate_object(node, value.is_object() ? value : json::object(), result, path, top);
    if (result.is_array()) result = validate_array(node, result, path);
    result = combinators(node, result, path);
    if (problems.size() == before)
      if (const auto spec = node.find("x-claim"); spec != node.end()) claims.push_back({&*spec, result, path});
    return result;
  }

  // A sub-run that reports nothing: does `value` satisfy `node`?
  // Conditions (if, contains, not) are JSON Schema's own: an object they describe may have other keys too.
  bool satisfies(const json& node, const json& value, const std::string& path) const {
    Validator trial(root_, rules_);
    trial.condition_ = true;
    (void)trial.validate(node, value, path);
    return trial.problems.empty();
  }

 private:
  void problem(const std::string& path, std::string what) { problems.push_back({path, std::move(what)}); }

  bool check_type(const json& node, const json& value, const std::string& path) {
    const auto types = types_of(node);
    if (types.empty()) return true;
    for (const auto& type : types)
      if (type_matches(type, value)) return true;
    problem(path, "expected " + expectation(node) + ", found " +
                      (value.is_string() ? std::string("string") : std::string(value.type_name())));
    return false;
  }

  void check_scalar(const json& node, const json& value, const std::string& path) {
    const std::string name = path.substr(path.find_last_of(".]") == std::string::npos ? 0 : path.find_last_of(".]") + 1);
    if (const auto choices = node.find("enum");
        choices != node.end() && std::find(choices->begin(), choices->end(), value) == choices->end()) {
      std::vector<std::string> listed;
      for (const auto& choice : *choices) listed.push_back(choice.dump());
      return problem(path, "expected one of " + joined(listed) + ", found " + describe(value, name, true));
    }
    if (const auto fixed = node.find("const"); fixed != node.end() && *fixed != value)
      return problem(path, node.value("errorMessage", "expected " + fixed->dump() + ", found " + describe(value, name, true)));
    if (value.is_number()) {
      const double number = value.get<double>();
      auto bound = [&](const char* key, auto&& fails) {
        const auto it = node.find(key);
        return it != node.end() && fails(number, it->get<double>());
      };
      if (!std::isfinite(number) || bound("minimum", [](double v, double b) { return v < b; }) ||
          bound("maximum", [](double v, double b) { return v > b; }) ||
          bound("exclusiveMinimum", [](double v, double b) { return v <= b; }) ||
          bound("exclusiveMaximum", [](double v, double b) { return v >= b; })) {
        const auto types = types_of(node);
        const bool integer = std::find(types.begin(), types.end(), "number") == types.end();
        return problem(path,
                       "expected " + std::string(integer ? "integer" : "number") + bounds(node) + ", found " + describe(value));
      }
    }
    if (value.is_string()) {
      const std::string text = value.get<std::string>();
      if (text.size() < node.value("minLength", 0u))
        return problem(path, node.value("minLength", 0u) == 1 ? "expected a non-empty string"
                                                              : "expected at least " + node["minLength"].dump() + " characters");
      if (node.contains("maxLength") && text.size() > node.value("maxLength", 0u))
        return problem(path, "expected at most " + node["maxLength"].dump() + " characters");
      if (const auto pattern = node.find("pattern"); pattern != node.end())
        if (!std::regex_search(text, std::regex(pattern->get<std::string>(), std::regex::ECMAScript)))
          return problem(path, node.value("errorMessage", "expected a string matching " + pattern->dump()) + ", found " +
                                   describe(value, name, true));
    }
  }

  // `written` is the object as given (dependentRequired looks at what was written, not at defaults).
  json validate_object(const json& node, const json& written, json result, const std::string& path, bool top) {
    static const json kNone = json::object();
    const json& properties = node.contains("properties") ? node.at("properties") : kNone;  // claims point into it
    for (const auto& name : required_of(root_, node)) {
      const auto it = result.find(name);
      if (it != result.end() && !it->is_null()) continue;
      const json* property = properties.contains(name) ? &properties[name] : nullptr;
      if (property != nullptr && property->contains("default")) continue;
      std::string what = "required";
      if (property != nullptr) {
        const json* target = reference(root_, *property);
        const json& shown = target != nullptr ? *target : *property;
        std::string text = property->value("description", shown.value("description", std::string()));
        what += " (" + expectation(shown) + (text.empty() ? "" : ": " + text) + ")";
      }
      problem(child(path, name), what);
    }
    for (const auto& [name, property] : properties.items()) {
      const auto it = result.find(name);
      if (it == result.end() || it->is_null()) {
        // A default goes through validation too (the manifest check made it valid): what it claims is claimed.
        const json* target = reference(root_, property);
        if (property.contains("default")) result[name] = validate(property, property["default"], child(path, name));
        else if (target != nullptr && target->contains("default"))
          result[name] = validate(property, (*target)["default"], child(path, name));
        else if (it != result.end()) result.erase(name);
        continue;
      }
      result[name] = validate(property, *it, child(path, name));
    }
    unknown_keys(node, properties, result, path, top);
    if (const auto min = node.find("minProperties"); min != node.end() && result.size() < min->get<std::size_t>())
      problem(path, "expected at least " + min->dump() + " entr" + (min->get<std::size_t>() == 1 ? "y" : "ies") + ", found " +
                        std::to_string(result.size()));
    if (const auto max = node.find("maxProperties"); max != node.end() && result.size() > max->get<std::size_t>())
      problem(path, "expected at most " + max->dump() + " entries, found " + std::to_string(result.size()));
    if (const auto dependent = node.find("dependentRequired"); dependent != node.end())
      for (const auto& [name, needed] : dependent->items())
        if (written.contains(name) && !written[name].is_null())
          for (const auto& other : needed)
            if (!written.contains(other.get<std::string>()) || written[other.get<std::string>()].is_null())
              problem(child(path, other.get<std::string>()), "required with " + name);
    if (const auto rules = node.find("x-rules"); rules != node.end())
      for (const auto& rule : *rules) {
        const SettingsRule parsed(rule.at("rule").get<std::string>());
        const auto holds = parsed.holds(result);
        if (!holds || *holds) continue;
        std::string found;
        for (const auto& name : parsed.names()) found += (found.empty() ? "" : ", ") + name + " = " + result[name].dump();
        problem(rule.contains("at") ? child(path, rule["at"].get<std::string>()) : path,
                rule.at("message").get<std::string>() + " (found " + found + ")");
      }
    return result;
  }

  void unknown_keys(const json& node, const json& properties, json& result, const std::string& path, bool top) {
    const auto extra = node.find("additionalProperties");
    // An object that lists its properties takes no others unless it says so; one that lists none is free-form.
    const bool closed =
        extra != node.end() ? extra->is_boolean() && !extra->get<bool>() : (top || node.contains("properties")) && !condition_;
    std::vector<std::string> allowed;
    for (const auto& [name, unused] : properties.items()) (void)unused, allowed.push_back(name);
    std::vector<std::string> unknown;
    for (auto& [key, value] : result.items()) {
      if (properties.contains(key)) continue;
      if (top && std::find(rules_.entry_keys.begin(), rules_.entry_keys.end(), key) != rules_.entry_keys.end() &&
          (rules_.legacy_schema || key == "id" || key == "protocol"))
        continue;
      if (extra != node.end() && extra->is_object()) {
        value = validate(*extra, value, child(path, key));
        continue;
      }
      if (!closed) continue;
      const std::string hint = closest_hint(key, allowed);
      if (top && rules_.unknown == UnknownKeys::WarnUnlessNearMiss && hint.empty()) {
        unknown.push_back(key);
        continue;
      }
      if (allowed.empty())
        problem(child(path, key), top ? "unknown key; this plugin takes no settings" : "unknown key; takes none");
      else problem(child(path, key), "unknown key; expected one of: " + joined(allowed) + hint);
    }
    for (const auto& key : unknown) {
      result.erase(key);
      ignored.push_back(key);
    }
  }

  json validate_array(const json& node, json result, const std::string& path) {
    const std::size_t size = result.size();
    if (const auto min = node.find("minItems"); min != node.end() && size < min->get<std::size_t>())
      problem(path, "expected at least " + min->dump() + " item" + (min->get<std::size_t>() == 1 ? "" : "s") + ", found " +
                        std::to_string(size));
    if (const auto max = node.find("maxItems"); max != node.end() && size > max->get<std::size_t>())
      problem(path, "expected at most " + max->dump() + " items, found " + std::to_string(size));
    const auto prefix = node.find("prefixItems");
    const std::size_t positional = prefix == node.end() ? 0 : prefix->size();
    for (std::size_t i = 0; i < std::min(size, positional); ++i)
      result[i] = validate((*prefix)[i], result[i], path + "[" + std::to_string(i) + "]");
    if (const auto items = node.find("items"); items != node.end())
      for (std::size_t i = positional; i < size; ++i)
        result[i] = validate(*items, result[i], path + "[" + std::to_string(i) + "]");
    if (node.value("uniqueItems", false))
      for (std::size_t i = 1; i < size; ++i)
        for (std::size_t j = 0; j < i; ++j)
          if (result[i] == result[j]) problem(path + "[" + std::to_string(i) + "]", "the same as item " + std::to_string(j));
    if (const auto contains = node.find("contains"); contains != node.end()) {
      bool any = false;
      for (std::size_t i = 0; i < size && !any; ++i) any = satisfies(*contains, result[i], path);
      if (!any)
        problem(path, contains->value("errorMessage",
                                      node.value("errorMessage", "expected an item that is " + form_summary(root_, *contains))));
    }
    return result;
  }

  json combinators(const json& node, json result, const std::string& path) {
    if (const auto all = node.find("allOf"); all != node.end())
      for (const auto& branch : *all) result = validate(branch, result, path);
    for (const char* keyword : {"oneOf", "anyOf"}) {
      const auto branches = node.find(keyword);
      if (branches == node.end()) continue;
      result = choose(node, *branches, result, path, std::string_view(keyword) == "oneOf");
    }
    if (const auto negated = node.find("not"); negated != node.end() && satisfies(*negated, result, path))
      problem(path, node.value("errorMessage", "must not be " + form_summary(root_, *negated)));
    if (const auto condition = node.find("if"); condition != node.end()) {
      const auto next = node.find(satisfies(*condition, result, path) ? "then" : "else");
      if (next != node.end()) {
        Validator trial(root_, rules_);
        trial.condition_ = condition_;
        json checked = trial.validate(*next, result, path);
        if (!trial.problems.empty() && next->contains("errorMessage")) {
          problem(path, next->value("errorMessage", std::string()));
        } else {
          merge(trial);
          result = std::move(checked);
        }
      }
    }
    return result;
  }

  // oneOf / anyOf: the branch the value satisfies; when none, the problems of the one branch whose required keys are
  // all there (what the writer evidently meant), else one "expected one of" naming the forms.
  json choose(const json& node, const json& branches, const json& value, const std::string& path, bool exactly_one) {
    std::vector<std::size_t> passing;
    std::vector<Validator> trials;
    for (std::size_t i = 0; i < branches.size(); ++i) {
      trials.emplace_back(root_, rules_);
      trials.back().condition_ = condition_;
      trials.back().result_ = trials.back().validate(branches[i], value, path);
      if (trials.back().problems.empty()) passing.push_back(i);
    }
    std::vector<std::string> forms;
    for (const auto& branch : branches) forms.push_back(form_summary(root_, branch));
    if (passing.size() == 1 || (!exactly_one && !passing.empty())) {
      merge(trials[passing.front()]);
      return trials[passing.front()].result_;
    }
    if (passing.size() > 1) {
      problem(path, node.value("errorMessage", "fits more than one of " + joined(forms, " | ")));
      return value;
    }
    std::vector<std::size_t> meant;
    if (value.is_object())
      for (std::size_t i = 0; i < branches.size(); ++i) {
        const auto required = required_of(root_, branches[i]);
        if (!required.empty() &&
            std::all_of(required.begin(), required.end(), [&](const std::string& r) { return value.contains(r); }))
          meant.push_back(i);
      }
    if (meant.empty() && value.is_object()) {  // no form complete: the one that knows most of the keys written
      std::size_t best = 0;
      for (std::size_t i = 0; i < branches.size(); ++i) {
        const json known = branches[i].value("properties", json::object());
        std::size_t count = 0;
        for (const auto& [key, unused] : value.items()) (void)unused, count += known.contains(key) ? 1 : 0;
        if (count > best) best = count, meant = {i};
        else if (count == best && count > 0) meant.push_back(i);
      }
    }
    if (meant.size() == 1) {
      merge(trials[meant.front()]);
      return value;
    }
    problem(path, node.value("errorMessage", "expected one of " + joined(forms, " | ")));
    return value;
  }

  void merge(Validator& other) {
    problems.insert(problems.end(), other.problems.begin(), other.problems.end());
    claims.insert(claims.end(), other.claims.begin(), other.claims.end());
  }

  const json& root_;
  SettingsRules rules_;
  json result_;             // a trial's outcome, for choose()
  bool condition_ = false;  // inside if, contains or not: objects are open
};

// The claims recorded during validation, resolved against the settings with defaults filled in.
inline std::vector<Claim> resolve_claims(const std::vector<PendingClaim>& pending, const json& settings) {
  std::vector<Claim> out;
  for (const auto& p : pending) {
    const json& spec = *p.spec;
    const auto* kind = claim_detail::find_kind(spec.at("resource").get<std::string>());
    if (kind == nullptr) continue;
    Claim claim;
    claim.resource = kind->name;
    claim.key = p.path;
    claim.value = p.value;
    if (const auto member = spec.find("value"); member != spec.end() && p.value.is_object())
      claim.value = p.value.value(member->get<std::string>(), json());
    if (claim.value.is_null()) continue;  // nothing named
    claim.value = claim_detail::normalise(kind->value, claim.value);
    const json scope = spec.value("scope", json::array());
    for (std::size_t i = 0; i < scope.size(); ++i) {
      const json& item = scope[i];
      const std::string pointer = item.is_string() ? item.get<std::string>() : item.value("pointer", std::string());
      json found;
      if (pointer.starts_with("/")) {
        const json::json_pointer at(pointer);
        if (settings.contains(at)) found = settings.at(at);
      } else if (p.value.is_object()) {
        found = p.value.value(pointer, json());
      }
      if (found.is_null() && item.is_object()) found = item.value("default", json());
      claim.scope.push_back(claim_detail::normalise(i < kind->scope.size() ? kind->scope[i] : claim_detail::Form::Text, found));
    }
    out.push_back(std::move(claim));
  }
  return out;
}

}  // namespace settings_detail
}  // namespace rcand::sdk::contract
