// Whether rcand maps a plugin's library at all: not when everything the robot needs of it is a capability that runs in
// a process of its own (`isolation: process`, issue 34). That process opens the library, through rcand's loader checks.
#pragma once

#include <nlohmann/json.hpp>

#include <set>
#include <string>

#include "libs/manifest/manifest.hpp"

namespace rcand {

// True when at least one of `capabilities` or `driver_protocols` is provided by `manifest`, and each one provided is a
// capability whose isolation (its manifest entry, overridden by `capability_settings`: runtime.capabilities) is
// process. A bad isolation setting is false: rcand then opens the plugin, and the capability's start names the fault.
bool served_apart(const PluginManifest& manifest, const std::set<std::string>& capabilities,
                  const std::set<std::string>& driver_protocols, const nlohmann::json& capability_settings);

}  // namespace rcand
