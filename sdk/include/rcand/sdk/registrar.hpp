// What a plugin's register function fills in. The kernel compares what is registered with the manifest's
// "provides": the two must be equal, or the plugin is recorded as manifest-mismatch and nothing of it runs.
#pragma once

#include <functional>
#include <memory>
#include <string>

#include "rcand/sdk/capability.hpp"
#include "rcand/sdk/context.hpp"
#include "rcand/sdk/driver.hpp"

namespace rcand::sdk {

struct CapabilityInfo {
  std::string name;       // "teleop", "com.acme.gripper"
  bool actuates = false;  // its routes move something (manifest provides[].actuates)
};
// Main thread; may block briefly; throw to fail the instance.
using CapabilityFactory = std::function<std::unique_ptr<Capability>(PluginContext&)>;

struct DriverInfo {
  std::string protocol;   // matched against `drivers[].protocol` in the robot config
  bool actuates = false;  // true: the factory returns an ActuatorDriver
  std::string interface;  // for actuators: ActuatorDriver::interface_name() of what the factory makes
};
// Main thread, once per `drivers[]` entry with this protocol; may block briefly; throw to fail the instance.
using DriverFactory = std::function<std::unique_ptr<Driver>(PluginContext&)>;

class RCAND_INTERFACE Registrar {
 public:
  virtual ~Registrar() = default;
  // Main thread, inside the plugin's register function only. Never block.
  virtual void add_capability(CapabilityInfo info, CapabilityFactory factory) = 0;
  virtual void add_driver(DriverInfo info, DriverFactory factory) = 0;
};

}  // namespace rcand::sdk
