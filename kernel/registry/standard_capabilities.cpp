#include "kernel/registry/standard_capabilities.hpp"

#include <array>
#include <utility>

namespace rcand::kernel {

// The kernel's names are the contract table's, in its order: one table, not two (issue 33).
static_assert(standard_capabilities().size() == 6 && standard_capabilities()[0].name == kStatusCapability &&
              standard_capabilities()[1].name == kNavCapability && standard_capabilities()[2].name == kTeleopCapability &&
              standard_capabilities()[3].name == kVisionCapability && standard_capabilities()[4].name == kChatCapability &&
              standard_capabilities()[5].name == kArmCapability);

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
