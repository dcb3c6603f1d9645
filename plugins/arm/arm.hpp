// The `arm` capability (RCAN §9): POST /api/action `arm_pose` (named joints, or a named pose from config) and
// `grip`, and GET /api/arm/joints. It drives a JointArm actuator through the kernel's motion gate, refusing any
// target outside a joint's limits, any step larger than max_step_deg, and any speed above max_velocity_dps, with a
// 400 that names the joint and the limit. Stopping is the driver's halt(): the arm holds its pose, torque on.
#pragma once

#include <rcand/sdk/interfaces/arm.hpp>
#include <rcand/sdk/plugin.hpp>

#include <cstdint>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "arm_rules.hpp"
#include "joint_limits.hpp"

namespace rcand::plugins::arm {

class ArmCapability final : public sdk::Capability {
 public:
  // Reads the joint limits (physics.kinematics, else the arm driver's joints[]), `driver`, `poses` and
  // `gripper_joint`. Throws sdk::ConfigError naming the key on anything wrong; an arm with no limits is refused.
  explicit ArmCapability(sdk::PluginContext& ctx);

  std::vector<sdk::Route> routes() override;
  sdk::Json status() const override;
  void on_estop() noexcept override;

  const std::vector<JointLimit>& limits() const noexcept { return limits_; }

 private:
  using Pose = std::vector<std::pair<std::string, double>>;

  sdk::Response arm_pose(const sdk::Request& request);
  sdk::Response grip(const sdk::Request& request);
  sdk::Response joints(const sdk::Request& request);
  // Reads the arm's present state, checks the request against the limits and sends it; `answer` gets the result.
  sdk::Response move(const MoveRequest& request, sdk::Json answer);
  // The configured `driver`, else the first joint_arm actuator, else the first actuator that is a JointArm.
  std::optional<std::string> resolve_arm() const;
  std::map<std::string, Pose> read_poses() const;
  void remember(sdk::Json command);
  void publish() noexcept;

  sdk::PluginContext& ctx_;
  const std::optional<std::string> configured_driver_;
  std::string limits_from_;  // where the limits were configured, for error texts
  const std::vector<JointLimit> limits_;
  const std::map<std::string, Pose> poses_;
  const std::optional<std::string> gripper_joint_;

  mutable std::mutex mutex_;  // the fields below
  sdk::Json last_command_;    // null until the first accepted command
  std::uint64_t commands_ = 0;
  std::uint64_t estops_ = 0;
};

}  // namespace rcand::plugins::arm
