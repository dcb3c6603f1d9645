// What a bid costs (docs/protocol.md §11: `cost` = estimated seconds to complete). Pluggable: the default is the nav time to the
// task location from the robot's fleet-frame pose, plus its queue; a plugin may install its own via R2rLink.
#pragma once

#include <cstddef>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "services/r2r/fleet_geometry.hpp"

namespace rcand::kernel::r2r {

struct TaskSpec {
  std::string task_id;
  std::string description;
  std::optional<double> deadline;  // Unix seconds (seed)
  std::vector<std::string> required_capabilities;
  std::optional<FleetPoint> location;  // fleet frame
};

struct CostInput {
  const TaskSpec& task;
  std::optional<FleetPose> position;  // fleet frame; nullopt when the robot does not know where it is
  std::size_t queue_length = 0;       // tasks this robot already holds
};

// Estimated seconds to complete the task; nullopt declines to bid. Called on the node's caller thread; must not block.
using CostFunction = std::function<std::optional<double>(const CostInput&)>;

// The robot's drive calibration (physics.* of the config, as nav reads it).
struct DrivePhysics {
  double wheel_circumference_m = 0.0;
  double turn_time_per_deg_s = 0.0;
  double max_wheel_rps = 1.0;
};

struct NavCostSettings {
  DrivePhysics physics;
  double speed = 0.5;              // the fraction of full speed nav would use (nav's default waypoint speed)
  double seconds_per_task = 30.0;  // what each queued task adds
};

// The default: turn to face the location, then drive to it, timed exactly as nav times a waypoint (nav's
// plan_waypoint), plus queue_length * seconds_per_task. A task without a location costs only the queue. Declines
// (nullopt) when the task has a location but the robot has no pose, or the physics are not set.
CostFunction nav_time_cost(NavCostSettings settings);

}  // namespace rcand::kernel::r2r
