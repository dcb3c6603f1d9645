#include "cost_function.hpp"

#include <cmath>
#include <exception>

namespace rcand::plugins::fleet {

Json task_fields(const TaskSpec& task) {
  Json fields{
      {"task_id", task.task_id}, {"description", task.description}, {"required_capabilities", task.required_capabilities}};
  if (task.deadline) fields["deadline"] = *task.deadline;
  if (task.location) fields["location"] = {{"x", task.location->x}, {"y", task.location->y}};
  return fields;
}

CostFunction trip_time_cost(TripEstimatorLookup estimator, TripCostSettings settings) {
  return [estimator = std::move(estimator), settings](const CostInput& input) -> std::optional<double> {
    const double queue_s = static_cast<double>(input.queue_length) * settings.seconds_per_task;
    if (!input.task.location) return queue_s;
    if (!input.position) return std::nullopt;  // cannot say how far it is
    const sdk::TripEstimator* trips = estimator ? estimator() : nullptr;
    if (trips == nullptr) return std::nullopt;  // nothing times a trip on this robot (no nav)
    const auto trip_s = trips->trip_seconds(*input.position, input.task.location->x, input.task.location->y, settings.speed);
    if (!trip_s || !std::isfinite(*trip_s) || *trip_s < 0) return std::nullopt;
    return *trip_s + queue_s;
  };
}

CostFunction plugin_cost(sdk::R2rCostFunction cost, sdk::Logger* log) {
  return [cost = std::move(cost), log](const CostInput& input) -> std::optional<double> {
    std::optional<sdk::R2rPose> pose;
    if (input.position) pose = sdk::R2rPose{input.position->x_m, input.position->y_m, input.position->heading_deg};
    try {
      return cost(task_fields(input.task), pose, input.queue_length);
    } catch (const std::exception& e) {
      if (log != nullptr) log->warn("a plugin's cost function threw (", e.what(), "); not bidding");
    } catch (...) {
      if (log != nullptr) log->warn("a plugin's cost function threw; not bidding");
    }
    return std::nullopt;
  };
}

}  // namespace rcand::plugins::fleet
