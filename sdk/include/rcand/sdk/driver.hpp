// Hardware drivers. One instance per `drivers[]` entry of the robot config whose `protocol` the plugin
// registered. Anything that moves derives from ActuatorDriver and is reachable only through the kernel's
// MotionGate: capabilities never hold a driver pointer.
#pragma once

#include <nlohmann/json.hpp>

#include <string_view>

#include "rcand/sdk/export.hpp"

namespace rcand::sdk {

class RCAND_INTERFACE Driver {
 public:
  virtual ~Driver() = default;
  // Main thread, once, before any command. May block (open a port, probe a bus). Throw to fail the instance.
  virtual void start() {}
  // A kernel thread, once, at shutdown (after halt() for actuators; in parallel with other drivers'). May block
  // briefly; one still running after 2 s is left behind.
  virtual void shutdown() noexcept {}
  // The instance's status thread, for /api/drivers/<id>. Thread-safe; must not block: one that has not returned
  // after 250 ms fails the instance and is never called again.
  virtual nlohmann::json status() const { return nlohmann::json::object(); }
};

class RCAND_INTERFACE ActuatorDriver : public Driver {
 public:
  // The interface this actuator implements ("differential_drive", "gripper", ...). Any thread; constant.
  virtual std::string_view interface_name() const noexcept = 0;
  // The e-stop. Called from the stop path (any thread, possibly concurrently with a command in progress).
  // Must stop the actuator and return once it is stopped; must not wait behind commands, queues or workers. One
  // kernel thread calls the actuators' halt() one after another; those it has not reached within 200 µs are called
  // on threads of their own, so a slow halt() delays the others by that much at most.
  virtual void halt() noexcept = 0;
};

// A two-wheel differential drive. Commands come only through MotionGate::actuate on a handler or worker thread.
class RCAND_INTERFACE DifferentialDrive : public ActuatorDriver {
 public:
  static constexpr std::string_view kInterface = "differential_drive";
  std::string_view interface_name() const noexcept override { return kInterface; }
  // Wheel speeds as fractions of full speed, each in [-1, 1] (the caller clamps). Thread-safe against halt().
  // May block for the hardware round-trip only.
  virtual void set_wheel_speeds(double left, double right) = 0;
};

}  // namespace rcand::sdk
