// Driver protocol names that configs written for other runtimes use. Where the hardware is what one of rcand's
// plugins drives, the name is read as rcand's (an alias); where rcand has no plugin for that hardware, --check-config
// says what it is and what would serve it. Aliases the plugins themselves declare in their manifests (pca9685_i2c,
// dynamixel_v2) need no entry here.
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "libs/yaml/diagnostic.hpp"

namespace rcand::config {

struct ProtocolAlias {
  std::string_view written;   // as other runtimes write it (compared without regard to case)
  std::string_view protocol;  // rcand's protocol for the same hardware
  std::string_view hardware;  // what both drive, for the warning
};

// The alias for `written`, or nullopt when rcand knows no other name for it.
std::optional<ProtocolAlias> protocol_alias(std::string_view written) noexcept;

// Why no installed plugin serves `protocol` and what would: "" when rcand knows nothing about that name.
std::string unserved_protocol_advice(std::string_view protocol);

// `diagnostic` with the advice appended when it says that no installed plugin serves drivers[i].protocol;
// `protocols` are the file's drivers' protocols, in order.
yaml::ConfigDiagnostic with_protocol_advice(yaml::ConfigDiagnostic diagnostic, const std::vector<std::string>& protocols);

}  // namespace rcand::config
