// Positions in the fleet frame (docs/protocol.md §11): each robot's dead-reckoned pose plus its runtime.r2r.origin offset.
#pragma once

namespace rcand::kernel::r2r {

struct FleetPose {
  double x = 0.0;  // metres
  double y = 0.0;
  double heading_deg = 0.0;  // counter-clockwise positive
};

struct FleetPoint {
  double x = 0.0;
  double y = 0.0;
};

// `pose` (the robot's own dead-reckoned frame) placed in the fleet frame by `origin` (where the robot's frame
// starts in the fleet frame): rotate by origin.heading_deg, then translate.
FleetPose to_fleet_frame(const FleetPose& pose, const FleetPose& origin) noexcept;

}  // namespace rcand::kernel::r2r
