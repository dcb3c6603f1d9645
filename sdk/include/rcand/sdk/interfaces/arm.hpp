// A jointed arm commanded in joint space (RCAN §9 `arm`). A driver implements it next to ActuatorDriver, and
// the arm capability reaches it only through the motion gate:
//   ctx.motion().actuate_as<rcand::sdk::JointArm>(id, [&](rcand::sdk::JointArm& arm) { arm.set_joint_targets(t); });
// It is a mixin rather than an ActuatorDriver subclass so that a driver with another primary interface (a PCA9685
// board driving wheels and a few servos) can offer its servo joints too: actuate_as cross-casts to it.
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "rcand/sdk/export.hpp"

namespace rcand::sdk {

struct JointTarget {
  std::string joint;
  double position_deg = 0.0;
  double velocity_dps = 0.0;  // > 0: how fast this joint may travel to the target
};

struct JointState {
  std::string joint;
  // Last position read, or nullopt when the read failed: never a made-up 0.0 an arm could be commanded from.
  std::optional<double> position_deg;
  double target_deg = 0.0;
  double velocity_dps = 0.0;  // the speed of the current move (0 when holding)
  bool moving = false;
  bool torque_on = false;
};

class RCAND_INTERFACE JointArm {
 public:
  // The interface name of an actuator whose primary job is an arm (ActuatorDriver::interface_name()).
  static constexpr std::string_view kInterface = "joint_arm";
  virtual ~JointArm() = default;
  // Through the motion gate only. Each named joint travels to position_deg at up to velocity_dps; joints not
  // named keep their target. The caller checked limits; the driver still refuses (std::invalid_argument naming the
  // joint) a joint it does not have or a position outside its own range, and applies nothing then. Thread-safe
  // against ActuatorDriver::halt(), which for an arm means: hold the current position, torque on.
  virtual void set_joint_targets(const std::vector<JointTarget>& targets) = 0;
  // Any thread; a brief lock at most. Every joint, in the driver's order.
  virtual std::vector<JointState> joint_states() const = 0;
};

}  // namespace rcand::sdk
