// What a manifest's "provides" items say about the robot as a whole, beyond each instance's settings: the settings
// schema of an item ("config", else the manifest's), the robot-config blocks an item reads ("reads": vision's
// camera), and the services an item offers or needs under a config condition ("offers", "needs": nav and teleop need
// the depth zones when camera.depth is set, vision offers them). A host checks the plan - the capabilities it will
// start and the drivers configured - with these before anything starts, so a robot that would start and then refuse
// every move is named at the config line instead. Pure and header-only; the kernel and the fake host call it.
#pragma once

#include <nlohmann/json.hpp>

#include <string>
#include <string_view>
#include <vector>

#include "settings.hpp"

namespace rcand::sdk::contract {

namespace plan_detail {

using nlohmann::json;

inline const json* find_dotted(const json& root, std::string_view dotted) {
  const json* node = &root;
  while (!dotted.empty()) {
    const auto dot = dotted.find('.');
    if (!node->is_object()) return nullptr;
    const auto it = node->find(std::string(dotted.substr(0, dot)));
    if (it == node->end()) return nullptr;
    node = &*it;
    dotted = dot == std::string_view::npos ? std::string_view{} : dotted.substr(dot + 1);
  }
  return node;
}

inline bool dotted_key(const json& value) {
  if (!value.is_string() || value.get<std::string>().empty()) return false;
  const std::string text = value.get<std::string>();
  return text.front() != '.' && text.back() != '.' && text.find("..") == std::string::npos;
}

inline void check_keys(const json& list, const std::string& field) {
  if (!list.is_array() || list.empty() || !std::all_of(list.begin(), list.end(), dotted_key))
    throw SettingsError(field, "expected a non-empty list of dotted config keys (\"camera.depth\")");
}

inline void check_service_use(const json& uses, const std::string& field, bool need) {
  if (!uses.is_array())
    throw SettingsError(field, "expected a list of {service, what, when" + std::string(need ? ", when_any?, without}" : "?}"));
  for (std::size_t i = 0; i < uses.size(); ++i) {
    const std::string at = field + "[" + std::to_string(i) + "]";
    const json& use = uses[i];
    if (!use.is_object()) throw SettingsError(at, "expected an object");
    for (const auto& [key, value] : use.items()) {
      const bool known = key == "service" || key == "what" || key == "when" || (need && (key == "when_any" || key == "without"));
      if (!known) throw SettingsError(at + "." + key, "unknown key");
      if ((key == "service" || key == "what" || key == "without") && (!value.is_string() || value.get<std::string>().empty()))
        throw SettingsError(at + "." + key, "expected a non-empty string");
      if (key == "when" || key == "when_any") check_keys(value, at + "." + key);
    }
    if (!use.contains("service") || !use.contains("what")) throw SettingsError(at, "service and what are required");
    if (need && !use.contains("when")) throw SettingsError(at + ".when", "required: a need holds only under a config condition");
  }
}

}  // namespace plan_detail

// A config key "is set": present, not null, not false ("camera.depth: synthetic").
inline bool config_key_set(const nlohmann::json& robot, std::string_view dotted) {
  const auto* node = plan_detail::find_dotted(robot, dotted);
  return node != nullptr && !node->is_null() && !(node->is_boolean() && !node->get<bool>());
}

// The manifest check of one "provides" item's own keys: "config" and each "reads" block are settings schemas; "offers"
// and "needs" are well-formed. Throws SettingsError naming the field ("provides[0].reads.camera.type: ...").
inline void check_provided_item(const nlohmann::json& item, const std::string& field) {
  if (const auto config = item.find("config"); config != item.end()) check_settings_schema(*config, field + ".config.");
  if (const auto reads = item.find("reads"); reads != item.end()) {
    if (!reads->is_object()) throw SettingsError(field + ".reads", "expected {config block: settings schema}");
    for (const auto& [block, schema] : reads->items()) {
      if (!plan_detail::dotted_key(block)) throw SettingsError(field + ".reads", "expected top-level config keys");
      check_settings_schema(schema, field + ".reads." + block + ".");
    }
  }
  if (const auto offers = item.find("offers"); offers != item.end())
    plan_detail::check_service_use(*offers, field + ".offers", false);
  if (const auto needs = item.find("needs"); needs != item.end()) plan_detail::check_service_use(*needs, field + ".needs", true);
}

// One item of the plan: a capability to start or a configured driver, with its manifest's "provides" entry.
struct PlannedItem {
  std::string kind;       // "capability" or "driver"
  std::string name;       // capability name, or driver protocol
  std::string plugin_id;  // whose manifest
  nlohmann::json item;    // the "provides" entry
};

// Every need of a planned item whose condition holds in `robot` and that no planned item offers (with its own
// condition holding): one problem per service and condition, at the condition's first key ("camera.depth"), naming
// who needs it, what would offer it among `installed` (everything the installed manifests provide) and what happens
// otherwise.
inline std::vector<SettingsProblem> unmet_needs(const std::vector<PlannedItem>& planned,
                                                const std::vector<PlannedItem>& installed, const nlohmann::json& robot) {
  using nlohmann::json;
  auto holds = [&](const json& use) {
    for (const auto& key : use.value("when", json::array()))
      if (!config_key_set(robot, key.get<std::string>())) return false;
    const json any = use.value("when_any", json::array());
    return any.empty() ||
           std::any_of(any.begin(), any.end(), [&](const json& key) { return config_key_set(robot, key.get<std::string>()); });
  };
  auto offered = [&](const std::vector<PlannedItem>& items, const std::string& service, bool condition) {
    std::vector<const PlannedItem*> out;
    for (const auto& p : items)
      for (const auto& offer : p.item.value("offers", json::array()))
        if (offer.value("service", "") == service && (!condition || holds(offer))) out.push_back(&p);
    return out;
  };
  std::vector<SettingsProblem> problems;
  std::vector<std::string> reported;  // service + condition, once
  for (const auto& p : planned)
    for (const auto& need : p.item.value("needs", json::array())) {
      const std::string service = need.value("service", "");
      if (!holds(need) || !offered(planned, service, true).empty()) continue;
      const std::string where = need["when"][0].get<std::string>();
      if (std::find(reported.begin(), reported.end(), service + "\n" + where) != reported.end()) continue;
      reported.push_back(service + "\n" + where);
      std::string who;
      for (const auto& q : planned)
        for (const auto& other : q.item.value("needs", json::array()))
          if (other.value("service", "") == service && holds(other)) who += (who.empty() ? "" : " and ") + q.kind + " " + q.name;
      std::string problem = where + " is set, so " + who + " need" + (who.find(" and ") == std::string::npos ? "s " : " ") +
                            need.value("what", service) + " (" + service + "), which nothing this robot starts offers";
      const auto offering = offered(installed, service, false);
      for (std::size_t i = 0; i < offering.size(); ++i)
        problem += std::string(i == 0 ? ": add " : " or ") + offering[i]->kind + " " + offering[i]->name + " (plugin " +
                   offering[i]->plugin_id + ")" + (offering[i]->kind == "capability" ? " to rcan_protocol.capabilities" : "");
      problem += std::string(offering.empty() ? "" : ",") + " or remove " + where;
      if (need.contains("without")) problem += "; as it is, " + need["without"].get<std::string>();
      problems.push_back({where, std::move(problem)});
    }
  return problems;
}

}  // namespace rcand::sdk::contract
