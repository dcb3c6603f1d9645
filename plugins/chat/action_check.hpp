// A brain's proposed action checked before anything runs: it must be one request a client could send to a
// capability this robot declares (never chat's own route, never a config or e-stop-clearing route), with a body whose
// numbers sit inside the robot's bounds. Out of bounds is refused, never clamped: a brain that asks for 5 m when the
// limit is 2 m has misread the instruction, and driving 2 m would hide that. The capability's own handler validates
// again when the request is dispatched; this check is what a brain cannot talk its way past.
#pragma once

#include <rcand/sdk/http.hpp>
#include <rcand/sdk/scope.hpp>

#include <cstdint>
#include <string>
#include <variant>
#include <vector>

namespace rcand::plugins::chat {

struct ActionLimits {
  std::vector<std::string> declared;     // rcan_protocol.capabilities
  double max_linear_speed = 1.0;         // safety.max_linear_speed (at most 1: wheel speeds are fractions)
  double max_distance_m = 5.0;           // chat's own bound on one brain-proposed drive
  double max_turn_deg = 360.0;           // and on one turn
  int max_duration_ms = 10000;           // and on one timed move
  std::int64_t nav_max_job_ms = 600000;  // runtime.capabilities.nav.max_job_ms
  double wheel_circumference_m = 0.0;    // physics, for a waypoint's duration (0: unknown)
  double turn_time_per_deg_s = 0.0;
  double max_wheel_rps = 1.0;
};

struct CheckedAction {
  std::string method, path;
  sdk::Json body;          // null for a GET
  std::string capability;  // "teleop", "com.acme.gripper"; "" for rcand's own routes (POST /api/stop, GET /api/status)
  sdk::Scope scope = sdk::Scope::Control;  // what the caller needs for it
  bool motion = true;  // may move something: never dispatched once the e-stop latched after the instruction came in
  bool stop = false;   // POST /api/stop: always dispatched
};

// The checked action, or the refusal: 404 CAPABILITY_NOT_FOUND for an undeclared capability, 422 ACTION_REJECTED
// naming the field for anything else. Both carry "field": "action".
std::variant<CheckedAction, sdk::Response> check_action(const sdk::Json& action, const ActionLimits& limits);

}  // namespace rcand::plugins::chat
