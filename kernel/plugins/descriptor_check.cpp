#include "kernel/plugins/descriptor_check.hpp"

#include <cstddef>
#include <cstdio>

namespace rcand::kernel {
namespace {

// The ABI 1.0 layout ends with register_plugin; fields appended later make the struct larger.
constexpr std::size_t kMinimumSize = offsetof(rcand_plugin_descriptor, register_plugin) + sizeof(void (*)());
const std::string kKernelAbi = std::to_string(RCAND_ABI_MAJOR) + "." + std::to_string(RCAND_ABI_MINOR);
DescriptorVerdict incompatible(std::string reason, std::string hint = rebuild_hint()) {
  return {PluginState::IncompatibleAbi, std::move(reason), std::move(hint)};
}

}  // namespace

std::string rebuild_hint() { return "rebuild against rcand-sdk " + std::to_string(RCAND_ABI_MAJOR) + ".x"; }

std::optional<DescriptorVerdict> check_descriptor(const rcand_plugin_descriptor* d, const PluginManifest& manifest) {
  if (d == nullptr) return incompatible("the entry point returned no descriptor", "build it with RCAND_PLUGIN");
  if (d->magic != RCAND_DESCRIPTOR_MAGIC) {
    char text[96];
    std::snprintf(text, sizeof text, "descriptor magic 0x%08x is not 0x%08x (\"RCND\")", static_cast<unsigned>(d->magic),
                  static_cast<unsigned>(RCAND_DESCRIPTOR_MAGIC));
    return incompatible(text, "build it with RCAND_PLUGIN");
  }
  if (d->struct_size < kMinimumSize)
    return incompatible("descriptor size " + std::to_string(d->struct_size) + " is smaller than the ABI 1.0 layout (" +
                        std::to_string(kMinimumSize) + " bytes)");
  if (d->struct_size > sizeof(rcand_plugin_descriptor))
    return incompatible("descriptor size " + std::to_string(d->struct_size) + " is larger than the kernel's (" +
                            std::to_string(sizeof(rcand_plugin_descriptor)) + " bytes): built against a newer SDK",
                        "upgrade rcand, or " + rebuild_hint());
  if (d->abi_major != RCAND_ABI_MAJOR)
    return incompatible("built for ABI " + std::to_string(d->abi_major) + ", kernel speaks " + std::to_string(RCAND_ABI_MAJOR));
  if (d->abi_minor > RCAND_ABI_MINOR)
    return incompatible("built for ABI " + std::to_string(d->abi_major) + "." + std::to_string(d->abi_minor) +
                            ", kernel speaks " + kKernelAbi + " (minor newer than the kernel's)",
                        "upgrade rcand, or " + rebuild_hint());
  if (d->register_plugin == nullptr) return incompatible("descriptor has no register function", "build it with RCAND_PLUGIN");

  const std::string mismatch_hint =
      "make RCAND_PLUGIN(id, version, ...) and " + manifest.file.filename().string() + " agree, then rebuild";
  if (d->plugin_id == nullptr || manifest.id != d->plugin_id)
    return DescriptorVerdict{PluginState::ManifestMismatch,
                             "descriptor id '" + std::string(d->plugin_id ? d->plugin_id : "(null)") +
                                 "' differs from manifest id '" + manifest.id + "'",
                             mismatch_hint};
  if (d->version == nullptr || manifest.version != d->version)
    return DescriptorVerdict{PluginState::ManifestMismatch,
                             "descriptor version '" + std::string(d->version ? d->version : "(null)") +
                                 "' differs from manifest version '" + manifest.version + "'",
                             mismatch_hint};
  return std::nullopt;
}

}  // namespace rcand::kernel
