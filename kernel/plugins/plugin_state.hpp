// Where a plugin ended up after scanning and loading. Failures are recorded, never fatal.
#pragma once

#include <string_view>

namespace rcand::kernel {

enum class PluginState {
  Loaded,               // opened, checked and registered: its capabilities and drivers can be instantiated
  InstalledNotEnabled,  // valid manifest; not opened (nothing it provides is needed, or another provider won)
  FailedToOpen,         // dlopen failed (missing file, undefined symbol) or no entry symbol
  IncompatibleAbi,      // built for another ABI major, a newer minor, or a descriptor layout the kernel rejects
  ManifestMismatch,     // descriptor id/version or registered set differs from the manifest
  RegistrationFailed,   // register threw, registered something invalid, or a name another plugin owns
  DuplicateId,          // another manifest with the same id was scanned first
  InvalidManifest,      // unreadable, bad JSON, or a missing or mistyped field
  Failed,               // loaded, but an instance failed at run time (set by the kernel core)
};

// "loaded", "installed-not-enabled", "failed-to-open", "incompatible-abi", "manifest-mismatch",
// "registration-failed", "duplicate-id", "invalid-manifest", "failed".
std::string_view to_string(PluginState s) noexcept;

// Everything except Loaded and InstalledNotEnabled.
bool is_failure(PluginState s) noexcept;

}  // namespace rcand::kernel
