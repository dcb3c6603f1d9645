// The Registrar the kernel hands a plugin's register function: it only records, so the kernel can compare
// the result with the manifest before anything of the plugin is used.
#pragma once

#include <string>
#include <vector>

#include "kernel/plugins/plugin_record.hpp"

namespace rcand::kernel::detail {

class RecordingRegistrar final : public sdk::Registrar {
 public:
  void add_capability(sdk::CapabilityInfo info, sdk::CapabilityFactory factory) override {
    if (info.name.empty()) return error("a capability was registered with an empty name");
    if (!factory) return error("capability '" + info.name + "' was registered without a factory");
    for (const auto& c : capabilities)
      if (c.info.name == info.name) return error("capability '" + info.name + "' was registered twice");
    capabilities.push_back({std::move(info), std::move(factory)});
  }

  void add_driver(sdk::DriverInfo info, sdk::DriverFactory factory) override {
    if (info.protocol.empty()) return error("a driver was registered with an empty protocol");
    if (!factory) return error("driver '" + info.protocol + "' was registered without a factory");
    for (const auto& d : drivers)
      if (d.info.protocol == info.protocol) return error("driver '" + info.protocol + "' was registered twice");
    drivers.push_back({std::move(info), std::move(factory)});
  }

  std::vector<RegisteredCapability> capabilities;
  std::vector<RegisteredDriver> drivers;
  std::vector<std::string> errors;  // misuse is recorded, not thrown: the plugin sees no kernel exceptions

 private:
  void error(std::string message) { errors.push_back(std::move(message)); }
};

}  // namespace rcand::kernel::detail
