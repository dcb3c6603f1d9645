// The dead-reckoned pose (docs/protocol.md §8): integrated from the time each phase actually ran, in the frame of the pose at
// startup (x forward, y left, heading counter-clockwise positive).
#pragma once

#include <cmath>
#include <numbers>

namespace rcand::plugins::nav {

struct Pose {
  double x_m = 0.0;
  double y_m = 0.0;
  double heading_deg = 0.0;  // folded into (-180, 180]

  Pose turned(double degrees) const noexcept {
    Pose next = *this;
    double h = std::remainder(heading_deg + degrees, 360.0);  // [-180, 180]
    if (h <= -180.0) h += 360.0;
    next.heading_deg = h == 0.0 ? 0.0 : h;  // no "-0" in status
    return next;
  }
  Pose driven(double metres) const noexcept {
    Pose next = *this;
    const double rad = heading_deg * std::numbers::pi / 180.0;
    next.x_m += metres * std::cos(rad);
    next.y_m += metres * std::sin(rad);
    return next;
  }
};

}  // namespace rcand::plugins::nav
