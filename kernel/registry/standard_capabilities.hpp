// The standard capabilities of RCAN §9 as the kernel sees them: the SDK's contract table (scope, mounts, action
// types: sdk/include/rcand/sdk/contract/requests.hpp, shared with the fake host) plus the first-party plugin and
// Debian package that provide each one. The kernel names a standard capability nowhere else
// (tests/check_kernel_shape.py checks that), so a new one is one row in the contract and one here.
#pragma once

#include <span>
#include <string_view>

#include "rcand/sdk/contract/requests.hpp"

namespace rcand::kernel {

inline constexpr std::string_view kStatusCapability = "status";
inline constexpr std::string_view kNavCapability = "nav";
inline constexpr std::string_view kTeleopCapability = "teleop";
inline constexpr std::string_view kVisionCapability = "vision";
inline constexpr std::string_view kChatCapability = "chat";
inline constexpr std::string_view kArmCapability = "arm";

using sdk::contract::capability_of_action;
using sdk::contract::standard_capabilities;
using sdk::contract::StandardCapability;
inline const StandardCapability* find_standard_capability(std::string_view name) noexcept {
  return sdk::contract::find_standard(name);
}

struct FirstPartyProvider {
  std::string_view plugin;   // the first-party plugin that provides it
  std::string_view package;  // the Debian package that ships that plugin
};
// For a standard capability; empty strings for another name.
FirstPartyProvider first_party_provider(std::string_view capability) noexcept;

}  // namespace rcand::kernel
