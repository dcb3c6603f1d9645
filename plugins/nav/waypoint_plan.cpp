#include "waypoint_plan.hpp"

#include <cmath>
#include <numbers>
#include <string>

namespace rcand::plugins::nav {

namespace {

using sdk::Json;
using sdk::Response;

double positive_physics(const sdk::ConfigView& config, const char* key, std::optional<double> fallback) {
  const std::string path = std::string("physics.") + key;
  const auto value = config.get<double>(path);  // throws ConfigError naming the path on a wrong type
  if (!value && !fallback)
    throw sdk::ConfigError(path + ": required for nav (§10.2): a number > 0");
  const double v = value.value_or(fallback.value_or(0.0));
  if (!std::isfinite(v) || v <= 0.0) throw sdk::ConfigError(path + ": expected a number > 0, found " + std::to_string(v));
  return v;
}

// A finite number, or the 400 naming `field`. `required` fields must be present.
std::optional<Response> read_number(const Json& body, const char* field, bool required, std::optional<double>& out) {
  const auto it = body.find(field);
  if (it == body.end() || it->is_null()) {
    if (required) return Response::bad_request(field, std::string(field) + " is required: a number");
    return std::nullopt;
  }
  if (!it->is_number())
    return Response::bad_request(field, std::string(field) + " must be a number, found " + it->type_name());
  const double value = it->get<double>();
  if (!std::isfinite(value)) return Response::bad_request(field, std::string(field) + " must be a finite number");
  out = value;
  return std::nullopt;
}

std::int64_t to_us(double seconds) { return static_cast<std::int64_t>(std::llround(seconds * 1e6)); }

}  // namespace

PhaseSeconds phase_seconds(const Waypoint& waypoint, const Physics& physics) noexcept {
  return {std::abs(waypoint.heading_deg) * physics.turn_time_per_deg_s / waypoint.speed,
          std::abs(waypoint.distance_m) / physics.metres_per_s(waypoint.speed)};
}

std::optional<double> TripTiming::trip_seconds(const sdk::Pose2d& from, double to_x_m, double to_y_m,
                                               double speed) const noexcept {
  if (!(speed > 0.0 && speed <= 1.0)) return std::nullopt;  // as a waypoint's speed
  const double dx = to_x_m - from.x_m, dy = to_y_m - from.y_m;
  const double distance = std::hypot(dx, dy);
  const double turn =
      distance > 0 ? std::remainder(std::atan2(dy, dx) * 180.0 / std::numbers::pi - from.heading_deg, 360.0) : 0.0;
  const auto [turn_s, drive_s] = phase_seconds({distance, turn, speed}, physics_);
  if (!std::isfinite(turn_s + drive_s)) return std::nullopt;
  return turn_s + drive_s;
}

Physics Physics::from(const sdk::ConfigView& robot_config) {
  Physics p;
  p.wheel_circumference_m = positive_physics(robot_config, "wheel_circumference_m", std::nullopt);
  p.turn_time_per_deg_s = positive_physics(robot_config, "turn_time_per_deg_s", std::nullopt);
  p.max_wheel_rps = positive_physics(robot_config, "max_wheel_rps", 1.0);
  return p;
}

std::variant<Plan, sdk::Response> plan_waypoint(const sdk::Json& body, const Physics& physics, std::int64_t max_job_us) {
  if (!body.is_object())
    return Response::bad_request("body", "the body must be a JSON object with distance_m, heading_deg and speed");
  std::optional<double> distance, heading, speed;
  if (auto bad = read_number(body, "distance_m", true, distance)) return *bad;
  if (auto bad = read_number(body, "heading_deg", true, heading)) return *bad;
  if (auto bad = read_number(body, "speed", false, speed)) return *bad;
  if (speed && (*speed <= 0.0 || *speed > 1.0))
    return Response::bad_request("speed", "speed must be in (0, 1] (0 would never arrive), found " + body.at("speed").dump());

  Plan plan;
  plan.waypoint = {*distance, *heading, speed.value_or(0.5)};
  const auto [turn_s, drive_s] = phase_seconds(plan.waypoint, physics);
  const double max_s = static_cast<double>(max_job_us) / 1e6;
  // Checked in seconds before converting, so a huge value cannot overflow the microsecond count.
  if (turn_s + drive_s > max_s) {
    const char* field = drive_s >= turn_s ? "distance_m" : "heading_deg";
    return Response::bad_request(field, std::string(field) + " makes the job take " + std::to_string(turn_s + drive_s) +
                                            " s, more than the " + std::to_string(max_s) + " s allowed (max_job_ms)");
  }
  plan.turn_us = to_us(turn_s);
  plan.drive_us = to_us(drive_s);
  return plan;
}

}  // namespace rcand::plugins::nav
