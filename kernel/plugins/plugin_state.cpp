#include "kernel/plugins/plugin_state.hpp"

namespace rcand::kernel {

std::string_view to_string(PluginState s) noexcept {
  switch (s) {
    case PluginState::Loaded: return "loaded";
    case PluginState::InstalledNotEnabled: return "installed-not-enabled";
    case PluginState::FailedToOpen: return "failed-to-open";
    case PluginState::IncompatibleAbi: return "incompatible-abi";
    case PluginState::ManifestMismatch: return "manifest-mismatch";
    case PluginState::RegistrationFailed: return "registration-failed";
    case PluginState::DuplicateId: return "duplicate-id";
    case PluginState::InvalidManifest: return "invalid-manifest";
    case PluginState::Failed: return "failed";
  }
  return "failed";
}

bool is_failure(PluginState s) noexcept { return s != PluginState::Loaded && s != PluginState::InstalledNotEnabled; }

}  // namespace rcand::kernel
