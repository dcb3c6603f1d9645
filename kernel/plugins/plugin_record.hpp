// Everything the kernel knows about one scanned plugin.
#pragma once

#include <rcand/sdk/registrar.hpp>

#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "libs/manifest/manifest.hpp"
#include "kernel/plugins/plugin_state.hpp"

namespace rcand::kernel {

struct RegisteredCapability {
  sdk::CapabilityInfo info;
  sdk::CapabilityFactory factory;  // plugin code: call it through guarded_call
};

struct RegisteredDriver {
  sdk::DriverInfo info;
  sdk::DriverFactory factory;  // plugin code: call it through guarded_call
};

struct PluginRecord {
  std::filesystem::path manifest_file;
  std::optional<PluginManifest> manifest;  // nullopt when invalid
  std::string id, version, build_info;     // build_info from the descriptor once opened
  int abi_minor = 0;  // the descriptor's: which appended virtuals the plugin's objects have (stream_routes() from 2)
  PluginState state = PluginState::InstalledNotEnabled;
  std::string reason, hint;  // e.g. "built for ABI 2, kernel speaks 1" / "rebuild against rcand-sdk 1.x"
  // Filled only when state is Loaded (nothing of a failed plugin runs).
  std::vector<RegisteredCapability> capabilities;
  std::vector<RegisteredDriver> drivers;
  // Keeps the boost::dll::shared_library alive. Libraries are also opened RTLD_NODELETE, so code stays mapped
  // for the process lifetime even after every handle is gone (nothing made by a plugin can outlive its code).
  std::shared_ptr<void> library;
};

}  // namespace rcand::kernel
