#include "services/r2r/fleet_geometry.hpp"

#include <cmath>
#include <numbers>

namespace rcand::kernel::r2r {

FleetPose to_fleet_frame(const FleetPose& pose, const FleetPose& origin) noexcept {
  const double rad = origin.heading_deg * std::numbers::pi / 180.0;
  FleetPose out;
  out.x = origin.x + pose.x * std::cos(rad) - pose.y * std::sin(rad);
  out.y = origin.y + pose.x * std::sin(rad) + pose.y * std::cos(rad);
  double heading = std::remainder(pose.heading_deg + origin.heading_deg, 360.0);
  if (heading <= -180.0) heading += 360.0;
  out.heading_deg = heading == 0.0 ? 0.0 : heading;
  return out;
}

}  // namespace rcand::kernel::r2r
