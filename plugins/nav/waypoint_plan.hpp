// A waypoint request turned into a plan (seed §10.2-10.3, docs/protocol.md §8): validation that names the field at fault,
// and the dead-reckoning timing from the physics block. Pure functions, no I/O.
#pragma once

#include <rcand/sdk/interfaces/trip_estimator.hpp>
#include <rcand/sdk/plugin.hpp>

#include <cstdint>
#include <optional>
#include <variant>

namespace rcand::plugins::nav {

// The §10.2 calibration. Read once at startup.
struct Physics {
  double wheel_circumference_m = 0.0;  // metres per wheel revolution
  double turn_time_per_deg_s = 0.0;    // seconds per degree at speed 1.0
  double max_wheel_rps = 1.0;          // wheel revolutions per second at speed 1.0

  // physics.* of the robot config. Throws sdk::ConfigError naming the key when a field is missing, not a number,
  // or not > 0 (the kernel never declares nav without them, so this is a second line of defence).
  static Physics from(const sdk::ConfigView& robot_config);
  double metres_per_s(double speed) const noexcept { return wheel_circumference_m * max_wheel_rps * speed; }
  double degrees_per_s(double speed) const noexcept { return speed / turn_time_per_deg_s; }
};

struct Waypoint {
  double distance_m = 0.0;   // negative: reverse
  double heading_deg = 0.0;  // relative to the current facing, positive = counter-clockwise (left)
  double speed = 0.5;        // (0, 1]
};

struct Plan {
  Waypoint waypoint;
  std::int64_t turn_us = 0;   // |heading| * turn_time_per_deg_s / speed
  std::int64_t drive_us = 0;  // |distance| / (circumference * max_wheel_rps * speed)
  std::int64_t eta_ms() const noexcept { return (turn_us + drive_us + 500) / 1000; }
  // Wheel speeds for each phase (fractions of full speed).
  double turn_left() const noexcept { return waypoint.heading_deg > 0 ? -waypoint.speed : waypoint.speed; }
  double turn_right() const noexcept { return -turn_left(); }
  double drive_wheels() const noexcept { return waypoint.distance_m < 0 ? -waypoint.speed : waypoint.speed; }
};

// The two phases' durations in seconds at the waypoint's speed: |heading| * turn_time_per_deg_s / speed, and
// |distance| / (circumference * max_wheel_rps * speed). What a plan and a trip estimate both time.
struct PhaseSeconds {
  double turn_s = 0.0, drive_s = 0.0;
};
PhaseSeconds phase_seconds(const Waypoint& waypoint, const Physics& physics) noexcept;

// The request body checked field by field (docs/protocol.md §8): distance_m and heading_deg required finite numbers; speed
// optional (default 0.5), a finite number in (0, 1]. A plan longer than max_job_us is refused too. Returns the plan
// or the 400 answer naming the field. Never touches a motor.
std::variant<Plan, sdk::Response> plan_waypoint(const sdk::Json& body, const Physics& physics, std::int64_t max_job_us);

// nav's trip timing as a service (the R2R bid cost, a fleet plugin): turn to face the point the shorter way, then
// drive straight there, timed as that one waypoint would be. No job-length limit.
class TripTiming final : public sdk::TripEstimator {
 public:
  explicit TripTiming(const Physics& physics) : physics_(physics) {}
  std::optional<double> trip_seconds(const sdk::Pose2d& from, double to_x_m, double to_y_m, double speed) const noexcept override;

 private:
  const Physics physics_;
};

}  // namespace rcand::plugins::nav
