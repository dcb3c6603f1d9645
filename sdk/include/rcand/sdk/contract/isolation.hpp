// Where a capability's plugin code runs (issue 34, docs/protocol.md §7.19): "in_process", in rcand's own process (the
// default), or "process", in a process of its own (rcand-plugin-host), where a crash, an abort or a hang of the plugin
// ends only that process. A manifest's capability entry states the vendor's default ("isolation") and what its process
// needs beyond the host's sandbox ("isolation_needs": any of "network", "video", "serial"); the robot config's
// runtime.capabilities.<name> block overrides it ("isolation"), and bounds the process's resident memory
// ("isolation_memory_mb"; past it rcand ends the process, which then restarts). Both hosts read these keys here, beside
// the plugin's own settings. Pure and header-only.
#pragma once

#include <nlohmann/json.hpp>

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "settings.hpp"

namespace rcand::sdk::contract {

// The keys a runtime.capabilities.<name> block carries beside its plugin's settings.
inline constexpr std::array<std::string_view, 2> kCapabilityEntryKeys{"isolation", "isolation_memory_mb"};

struct Isolation {
  bool process = false;
  std::size_t memory_mb = 1024;
  // The manifest entry's "isolation_needs": its process may open IP sockets ("network"), cameras ("video": V4L2 and
  // media devices) and serial ports ("serial": ttyS/USB/ACM/AMA..., /dev/serial, pseudo-terminals).
  bool network = false;
  bool video = false;
  bool serial = false;
};

inline constexpr std::size_t kMinIsolationMemoryMb = 16;

// The isolation of a capability whose manifest entry is `provided` and whose settings block is `settings` (either may
// be null or lack the keys). Throws SettingsError naming the key at fault.
inline Isolation isolation_of(const nlohmann::json& provided, const nlohmann::json& settings) {
  const auto mode = [](const nlohmann::json& block, bool fallback) {
    if (!block.is_object() || !block.contains("isolation")) return fallback;
    const auto& value = block["isolation"];
    if (value == "process") return true;
    if (value == "in_process") return false;
    throw SettingsError("isolation", "expected \"process\" or \"in_process\", found " + value.dump());
  };
  Isolation isolation;
  isolation.process = mode(settings, mode(provided, false));
  if (provided.is_object() && provided.contains("isolation_needs")) {
    const auto& needs = provided["isolation_needs"];
    if (!needs.is_array()) throw SettingsError("isolation_needs", "expected a list such as [\"network\"], found " + needs.dump());
    for (const auto& need : needs) {
      if (need == "network") isolation.network = true;
      else if (need == "video") isolation.video = true;
      else if (need == "serial") isolation.serial = true;
      else
        throw SettingsError("isolation_needs",
                            "expected \"network\", \"video\" or \"serial\" (what its process may use "
                            "beyond the sandbox), found " +
                                need.dump());
    }
  }
  if (settings.is_object() && settings.contains("isolation_memory_mb")) {
    const auto& value = settings["isolation_memory_mb"];
    if (!value.is_number_integer() || value.get<std::int64_t>() < static_cast<std::int64_t>(kMinIsolationMemoryMb))
      throw SettingsError("isolation_memory_mb",
                          "expected integer >= " + std::to_string(kMinIsolationMemoryMb) + " (megabytes), found " + value.dump());
    isolation.memory_mb = value.get<std::size_t>();
  }
  return isolation;
}

// The settings of a capability: validate_settings() over its plugin's own keys; the isolation keys are checked here
// and left out of the result (the plugin never sees them).
inline SettingsResult validate_capability_settings(const nlohmann::json& schema, const nlohmann::json& settings,
                                                   UnknownKeys unknown) {
  nlohmann::json own = settings;
  if (own.is_object())
    for (const auto key : kCapabilityEntryKeys) own.erase(std::string(key));
  auto result = validate_settings(schema, own, SettingsRules{{}, unknown});
  try {
    isolation_of(nullptr, settings);
  } catch (const SettingsError& e) {
    result.problems.push_back({e.key(), e.problem()});
  }
  return result;
}

}  // namespace rcand::sdk::contract
