// The checks a plugin's descriptor must pass before the kernel calls anything in it (GStreamer's and OBS's
// rules): magic, struct size, ABI major equal and minor not newer, id and version equal to the manifest.
#pragma once

#include <rcand/sdk/abi.h>

#include <optional>
#include <string>

#include "libs/manifest/manifest.hpp"
#include "kernel/plugins/plugin_state.hpp"

namespace rcand::kernel {

struct DescriptorVerdict {
  PluginState state;  // IncompatibleAbi or ManifestMismatch
  std::string reason, hint;
};

// nullopt when `descriptor` is acceptable for `manifest`; otherwise why not. Reads only the fields that
// descriptor->struct_size says exist.
std::optional<DescriptorVerdict> check_descriptor(const rcand_plugin_descriptor* descriptor, const PluginManifest& manifest);

// The hint for a plugin built against another SDK major: "rebuild against rcand-sdk <major>.x".
std::string rebuild_hint();

}  // namespace rcand::kernel
