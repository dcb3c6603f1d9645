// The checks between an arm_pose request and the motors: every named joint exists, its target is inside its
// limits, it moves at most max_step_deg from where it is now, and no faster than max_velocity_dps. Pure (no gate,
// no clock), so each rule is tested on its own; a refusal is the HTTP answer naming the joint and the limit.
#pragma once

#include <rcand/sdk/http.hpp>
#include <rcand/sdk/interfaces/arm.hpp>

#include <optional>
#include <string>
#include <utility>
#include <variant>
#include <vector>

#include "joint_limits.hpp"

namespace rcand::plugins::arm {

struct MoveRequest {
  std::vector<std::pair<std::string, double>> targets;  // joint -> degrees, in request order
  std::optional<double> velocity_dps;  // absent: each joint's own max_velocity_dps; else in [kMinVelocityDps, it]
  bool cap_step = true;                                 // false for grip: opening a gripper is a full-range move
  std::string field = "joints";                         // the body field named in a refusal
};

// The targets to send, or the refusal: 400 BAD_REQUEST (unknown joint, out of range, step, speed) or 503
// UNAVAILABLE (the driver lacks the joint or could not read its position). `limits_from` names where the limits
// were configured, for the error text.
std::variant<std::vector<sdk::JointTarget>, sdk::Response> plan_move(const MoveRequest& request,
                                                                     const std::vector<JointLimit>& limits,
                                                                     const std::vector<sdk::JointState>& present,
                                                                     const std::string& limits_from);

// Longest eta_ms reported: 2^53 - 1, exact in a double and in every JSON reader. Only an absurd config (a range of
// 1e300 degrees) gets near it; the computation saturates there instead of overflowing the integer.
inline constexpr long long kMaxEtaMs = 9'007'199'254'740'991;

// The time the slowest joint needs, in ms (rounded up), at most kMaxEtaMs.
long long eta_ms(const std::vector<sdk::JointTarget>& targets, const std::vector<sdk::JointState>& present);

// "12.5", "120", "-90": numbers as people write them in errors.
std::string shortest(double value);

}  // namespace rcand::plugins::arm
