#include "kernel/registry/standard_capabilities.hpp"

#include <array>
#include <utility>

namespace rcand::kernel {

FirstPartyProvider first_party_provider(std::string_view capability) noexcept {
  static constexpr std::array<std::pair<std::string_view, FirstPartyProvider>, 6> kProviders{{
      {kStatusCapability, {"", "rcand"}},
      {kNavCapability, {"org.rcand.nav", "rcand-plugins-core"}},
      {kTeleopCapability, {"org.rcand.teleop", "rcand-plugins-core"}},
      {kVisionCapability, {"org.rcand.vision", "rcand-plugins-vision"}},
      {kChatCapability, {"org.rcand.chat", "rcand-plugins-core"}},
      {kArmCapability, {"org.rcand.arm", "rcand-plugins-hw"}},
  }};
  for (const auto& [name, provider] : kProviders)
    if (name == capability) return provider;
  return {};
}

}  // namespace rcand::kernel
