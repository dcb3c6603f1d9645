#include "libs/manifest/served_apart.hpp"

#include "rcand/sdk/contract/isolation.hpp"

namespace rcand {

bool served_apart(const PluginManifest& manifest, const std::set<std::string>& capabilities,
                  const std::set<std::string>& driver_protocols, const nlohmann::json& capability_settings) {
  bool any = false;
  for (const auto& item : manifest.provides) {
    if (!(item.kind == "driver" ? driver_protocols : capabilities).contains(item.name)) continue;
    if (item.kind == "driver") return false;  // drivers never leave rcand
    try {
      const auto settings = capability_settings.is_object() ? capability_settings.value(item.name, nlohmann::json()) : nullptr;
      if (!sdk::contract::isolation_of(item.entry, settings).process) return false;
    } catch (const sdk::contract::SettingsError&) {
      return false;
    }
    any = true;
  }
  return any;
}

}  // namespace rcand
