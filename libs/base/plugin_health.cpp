#include "libs/base/plugin_health.hpp"

namespace rcand {

using nlohmann::json;

json instances_by_plugin(const json& status_doc) {
  json out = json::object();
  const auto add = [&out](const char* kind, const std::string& name, const json& item) {
    if (!item.is_object()) return;
    const std::string plugin = item.value("plugin", "");
    if (plugin.empty()) return;  // its plugin never loaded: the plugin's own entry says why
    json instance{{kind, name}, {"state", item.value("state", "ok")}};
    for (const char* key : {"reason", "device", "os_error", "hint", "stale"})
      if (item.contains(key)) instance[key] = item[key];
    out[plugin].push_back(std::move(instance));
  };
  if (const auto it = status_doc.find("drivers"); it != status_doc.end() && it->is_array())
    for (const auto& item : *it) add("driver", item.is_object() ? item.value("id", "") : "", item);
  if (const auto it = status_doc.find("capabilities"); it != status_doc.end() && it->is_object())
    for (const auto& [name, item] : it->items()) add("capability", name, item);
  return out;
}

std::string plugin_health(std::string_view library_state, const json& instances) {
  if (library_state != "loaded") return library_state == "installed-not-enabled" ? "unused" : "error";
  if (!instances.is_array() || instances.empty()) return "unused";
  std::string health = "ok";
  for (const auto& instance : instances) {
    const std::string state = instance.value("state", "ok");
    if (state == "failed" || state == "error") return "error";
    if (state == "degraded") health = "degraded";
  }
  return health;
}

void add_plugin_health(json& plugins, const json& status_doc, bool with_instances) {
  if (!plugins.is_array()) return;
  const json by_plugin = instances_by_plugin(status_doc);
  for (auto& plugin : plugins) {
    if (!plugin.is_object()) continue;
    const std::string id = plugin.value("id", "");
    const json instances = by_plugin.contains(id) ? by_plugin[id] : json::array();
    plugin["health"] = plugin_health(plugin.value("state", ""), instances);
    if (with_instances) plugin["instances"] = instances;
  }
}

}  // namespace rcand
