// How long a trip takes, as a service (rcand/sdk/services.hpp). nav offers it, timed exactly as it would drive the
// trip as one waypoint; the fleet plugin (org.rcand.fleet) prices its R2R bids for a task at a location with it.
#pragma once

#include <optional>
#include <string_view>

#include "rcand/sdk/export.hpp"
#include "rcand/sdk/interfaces/pose_source.hpp"

namespace rcand::sdk {

class RCAND_INTERFACE TripEstimator {
 public:
  static constexpr std::string_view kServiceId = "rcand.trip_estimator/1";
  virtual ~TripEstimator() = default;
  // Seconds to turn from `from` to face (to_x_m, to_y_m), the shorter way, then drive straight there, at `speed` (a
  // fraction of full speed in (0, 1]). `from` and the point are in one frame, any frame. nullopt when it cannot say
  // (speed out of range, a value not finite). No job-length limit applies. Any thread, never blocks.
  virtual std::optional<double> trip_seconds(const Pose2d& from, double to_x_m, double to_y_m, double speed) const noexcept = 0;
};

}  // namespace rcand::sdk
