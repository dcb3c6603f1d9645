// The robot's pose as a service (rcand/sdk/services.hpp). nav offers it (its dead-reckoned pose, and whether a
// waypoint job is driving); rcand reads it for GET /api/status ("pose", "nav_running", "state": "running") and so
// does anything else that needs to know where the robot is.
#pragma once

#include <cmath>
#include <numbers>
#include <string_view>

#include "rcand/sdk/export.hpp"
#include "rcand/sdk/services.hpp"

namespace rcand::sdk {

// A pose in a plane: x forward and y left of the frame's origin, heading counter-clockwise from the x axis.
struct Pose2d {
  double x_m = 0.0;
  double y_m = 0.0;
  double heading_deg = 0.0;  // (-180, 180]
};

// `pose`, given in a frame whose own origin sits at `origin` in an outer frame, expressed in the outer frame: rotated
// by origin.heading_deg, then moved by (origin.x_m, origin.y_m); the heading stays in (-180, 180]. R2R's fleet frame
// is compose(runtime.r2r.origin, nav's pose) (docs/protocol.md §11.6).
inline Pose2d compose(const Pose2d& origin, const Pose2d& pose) noexcept {
  const double rad = origin.heading_deg * std::numbers::pi / 180.0;
  Pose2d out;
  out.x_m = origin.x_m + pose.x_m * std::cos(rad) - pose.y_m * std::sin(rad);
  out.y_m = origin.y_m + pose.x_m * std::sin(rad) + pose.y_m * std::cos(rad);
  double heading = std::remainder(pose.heading_deg + origin.heading_deg, 360.0);
  if (heading <= -180.0) heading += 360.0;
  out.heading_deg = heading == 0.0 ? 0.0 : heading;  // never -0
  return out;
}

struct PoseReading {
  bool available = false;  // false: the source does not know where the robot is; `pose` means nothing
  Pose2d pose;             // in the source's frame (nav: the robot's pose when rcand started)
  bool busy = false;       // true while the source drives the robot itself (nav: a waypoint job runs)
};

class RCAND_INTERFACE PoseSource {
 public:
  static constexpr std::string_view kServiceId = "rcand.pose_source/1";
  virtual ~PoseSource() = default;
  // The latest pose, including a motion in progress. Any thread, thread-safe, never blocks beyond a brief lock.
  virtual PoseReading read() const noexcept = 0;
};

}  // namespace rcand::sdk
