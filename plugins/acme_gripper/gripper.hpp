// The com.acme.gripper actuator interface. Capabilities reach it only through the rcand motion gate:
//   ctx.motion().actuate_as<acme::gripper::Gripper>(id, [&](acme::gripper::Gripper& g) { g.set_opening(0.5); });
#pragma once

#include <rcand/sdk/export.hpp>  // RCAND_INTERFACE
#include <rcand/sdk/driver.hpp>

#include <string_view>

namespace acme::gripper {

// Default visibility, so the dynamic_cast in actuate_as works across the plugin boundary.
class RCAND_INTERFACE Gripper : public rcand::sdk::ActuatorDriver {
 public:
  static constexpr std::string_view kInterface = "com.acme.gripper";
  std::string_view interface_name() const noexcept override { return kInterface; }
  // Through the motion gate only. 0 = closed, 1 = fully open; the jaws stop early on an object, and then
  // holding() is true. Thread-safe against halt(); may block for the hardware round-trip.
  virtual void set_opening(double opening) = 0;
  // Any thread, never blocks.
  virtual double opening() const = 0;
  virtual bool holding() const = 0;
};

}  // namespace acme::gripper
