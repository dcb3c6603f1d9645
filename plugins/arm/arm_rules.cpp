#include "arm_rules.hpp"

#include <rcand/sdk/bounded_text.hpp>

#include <algorithm>
#include <cmath>
#include <sstream>

namespace rcand::plugins::arm {

namespace {

using sdk::Json;
using sdk::Response;

// Positions within this of each other are equal: floating-point noise is not a step.
constexpr double kEpsilonDeg = 1e-9;

Response limit_refusal(const std::string& field, const std::string& joint, const char* limit, double limit_value,
                       double requested, std::string message) {
  return Response::error(
      400, "BAD_REQUEST", std::move(message),
      Json{{"field", field}, {"joint", joint}, {"limit", limit}, {"limit_value", limit_value}, {"requested", requested}});
}

const sdk::JointState* find_state(const std::vector<sdk::JointState>& present, const std::string& joint) {
  for (const auto& s : present)
    if (s.joint == joint) return &s;
  return nullptr;
}

}  // namespace

std::string shortest(double value) {
  std::ostringstream text;
  text << value;
  return text.str();
}

std::variant<std::vector<sdk::JointTarget>, Response> plan_move(const MoveRequest& request, const std::vector<JointLimit>& limits,
                                                                const std::vector<sdk::JointState>& present,
                                                                const std::string& limits_from) {
  if (request.targets.empty()) return Response::bad_request(request.field, request.field + " names no joint");
  if (request.velocity_dps && !(*request.velocity_dps >= JointLimit::kMinVelocityDps))  // NaN too
    return Response::error(400, "BAD_REQUEST",
                           "velocity_dps must be at least " + shortest(JointLimit::kMinVelocityDps) +
                               " deg/s and at most the moved joints' max_velocity_dps, found " + shortest(*request.velocity_dps),
                           Json{{"field", "velocity_dps"},
                                {"limit", "min_velocity_dps"},
                                {"limit_value", JointLimit::kMinVelocityDps},
                                {"requested", *request.velocity_dps}});

  std::vector<sdk::JointTarget> out;
  for (const auto& [joint, target] : request.targets) {
    const JointLimit* limit = find_joint(limits, joint);
    if (limit == nullptr) {  // the name is the caller's: quoted cut and made safe, in the text and the field
      Json allowed = Json::array();
      for (const auto& j : limits) allowed.push_back(j.joint);
      const std::string quoted = sdk::bounded_text(joint);
      return Response::error(400, "BAD_REQUEST", "unknown joint '" + quoted + "'",
                             Json{{"field", request.field + "." + quoted}, {"allowed", allowed}});
    }
    const std::string field = request.field + "." + joint;
    const std::string range = "[" + shortest(limit->min_deg) + ", " + shortest(limit->max_deg) + "]";
    if (!std::isfinite(target))
      return Response::bad_request(field, "joint '" + joint + "' target must be a finite number of degrees in " + range);
    if (target < limit->min_deg)
      return limit_refusal(field, joint, "min_deg", limit->min_deg, target,
                           "joint '" + joint + "' target " + shortest(target) + " deg is below its limit min_deg " +
                               shortest(limit->min_deg) + " (range " + range + ", " + limits_from + ")");
    if (target > limit->max_deg)
      return limit_refusal(field, joint, "max_deg", limit->max_deg, target,
                           "joint '" + joint + "' target " + shortest(target) + " deg is above its limit max_deg " +
                               shortest(limit->max_deg) + " (range " + range + ", " + limits_from + ")");
    const double velocity = request.velocity_dps.value_or(limit->max_velocity_dps);
    if (velocity > limit->max_velocity_dps)
      return limit_refusal("velocity_dps", joint, "max_velocity_dps", limit->max_velocity_dps, velocity,
                           "velocity_dps " + shortest(velocity) + " exceeds joint '" + joint + "' limit max_velocity_dps " +
                               shortest(limit->max_velocity_dps) + " (" + limits_from + ")");

    const sdk::JointState* state = find_state(present, joint);
    if (state == nullptr)
      return Response::error(503, "UNAVAILABLE",
                             "the arm driver has no joint '" + joint + "' (configured in " + limits_from + ")",
                             Json{{"joint", joint}});
    if (!state->position_deg || !std::isfinite(*state->position_deg))  // NaN would pass every step check
      return Response::error(503, "UNAVAILABLE",
                             "joint '" + joint + "' position could not be read; it is not moved from an unknown position",
                             Json{{"joint", joint}});
    const double step = std::abs(target - *state->position_deg);
    if (request.cap_step && step > limit->max_step_deg + kEpsilonDeg)
      return limit_refusal(field, joint, "max_step_deg", limit->max_step_deg, target,
                           "joint '" + joint + "' would move " + shortest(step) + " deg (from " + shortest(*state->position_deg) +
                               " to " + shortest(target) + "); its limit max_step_deg is " + shortest(limit->max_step_deg) +
                               " per command: move in smaller steps");
    out.push_back({joint, target, velocity});
  }
  return out;
}

long long eta_ms(const std::vector<sdk::JointTarget>& targets, const std::vector<sdk::JointState>& present) {
  double slowest_s = 0.0;
  for (const auto& t : targets) {
    const sdk::JointState* state = find_state(present, t.joint);
    if (state == nullptr || !state->position_deg || !std::isfinite(*state->position_deg) || !(t.velocity_dps > 0.0)) continue;
    slowest_s = std::max(slowest_s, std::abs(t.position_deg - *state->position_deg) / t.velocity_dps);
  }
  const double ms = std::ceil(slowest_s * 1000.0);
  // Converting a double beyond long long's range is undefined behaviour: saturate first (NaN, infinity included).
  return ms < static_cast<double>(kMaxEtaMs) ? static_cast<long long>(ms) : kMaxEtaMs;
}

}  // namespace rcand::plugins::arm
