// What a bid costs (docs/protocol.md §11.8: `cost` = estimated seconds to complete). The default is the trip time to
// the task location from the robot's fleet-frame pose, as the robot's TripEstimator service (nav's) times it, plus
// its queue; a plugin may install its own through R2rLink::set_cost_function, which rcand hands on to this plugin.
#pragma once

#include <rcand/sdk/interfaces/pose_source.hpp>
#include <rcand/sdk/interfaces/trip_estimator.hpp>
#include <rcand/sdk/logger.hpp>
#include <rcand/sdk/r2r.hpp>

#include <cstddef>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace rcand::plugins::fleet {

using sdk::Json;
using FleetPose = sdk::Pose2d;  // a pose in the fleet frame: sdk::compose(runtime.r2r.origin, the robot's own pose)

struct FleetPoint {
  double x = 0.0;  // metres, fleet frame
  double y = 0.0;
};

struct TaskSpec {
  std::string task_id;
  std::string description;
  std::optional<double> deadline;  // Unix seconds (seed)
  std::vector<std::string> required_capabilities;
  std::optional<FleetPoint> location;  // fleet frame
};

// The task_request fields of `task` (without bid_deadline): what a plugin's cost function is handed.
Json task_fields(const TaskSpec& task);

struct CostInput {
  const TaskSpec& task;
  std::optional<FleetPose> position;  // nullopt when the robot does not know where it is
  std::size_t queue_length = 0;       // tasks this robot already holds
};

// Estimated seconds to complete the task; nullopt declines to bid. Runs under the auction's lock: must not block.
using CostFunction = std::function<std::optional<double>(const CostInput&)>;

// Where the default cost finds the trip timing: sdk::find<sdk::TripEstimator>, asked at every bid (offers come and go
// with nav). Null, or an empty function: no estimator.
using TripEstimatorLookup = std::function<const sdk::TripEstimator*()>;

struct TripCostSettings {
  double speed = 0.5;              // the fraction of full speed nav would use (nav's default waypoint speed)
  double seconds_per_task = 30.0;  // what each queued task adds (runtime.r2r.cost_per_queued_task_s)
};

// The default: the estimator's trip seconds from the fleet pose to the location (nav: turn to face it, then drive, as
// one waypoint), plus queue_length * seconds_per_task. A task without a location costs only the queue. Declines
// (nullopt) when the task has a location but the robot has no pose, no estimator is offered (no nav), or the
// estimator cannot say.
CostFunction trip_time_cost(TripEstimatorLookup estimator, TripCostSettings settings);

// A plugin's R2rCostFunction as a CostFunction: handed the task's fields, the pose as an R2rPose and the queue. A
// throw counts as "no bid" (logged to `log` when given).
CostFunction plugin_cost(sdk::R2rCostFunction cost, sdk::Logger* log);

}  // namespace rcand::plugins::fleet
