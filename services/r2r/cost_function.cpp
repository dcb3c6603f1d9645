#include "services/r2r/cost_function.hpp"

#include <cmath>
#include <limits>
#include <numbers>
#include <variant>

#include "waypoint_plan.hpp"  // nav's own timing (plugins/nav), linked as rcand_nav_plan

namespace rcand::kernel::r2r {

CostFunction nav_time_cost(NavCostSettings settings) {
  return [settings](const CostInput& input) -> std::optional<double> {
    const double queue_s = static_cast<double>(input.queue_length) * settings.seconds_per_task;
    if (!input.task.location) return queue_s;
    if (!input.position) return std::nullopt;  // cannot say how far it is
    const DrivePhysics& p = settings.physics;
    if (!(p.wheel_circumference_m > 0) || !(p.turn_time_per_deg_s > 0) || !(p.max_wheel_rps > 0)) return std::nullopt;

    const double dx = input.task.location->x - input.position->x;
    const double dy = input.task.location->y - input.position->y;
    const double distance = std::hypot(dx, dy);
    // Turn to face the location (the shorter way), then drive straight: one nav waypoint.
    double turn = distance > 0 ? std::atan2(dy, dx) * 180.0 / std::numbers::pi - input.position->heading_deg : 0.0;
    turn = std::remainder(turn, 360.0);
    const plugins::nav::Physics physics{p.wheel_circumference_m, p.turn_time_per_deg_s, p.max_wheel_rps};
    const sdk::Json waypoint{{"distance_m", distance}, {"heading_deg", turn}, {"speed", settings.speed}};
    const auto plan = plugins::nav::plan_waypoint(waypoint, physics, std::numeric_limits<std::int64_t>::max() / 2);
    const auto* planned = std::get_if<plugins::nav::Plan>(&plan);
    if (planned == nullptr) return std::nullopt;
    return static_cast<double>(planned->turn_us + planned->drive_us) / 1e6 + queue_s;
  };
}

}  // namespace rcand::kernel::r2r
