// An arm's joints and their limits, as the robot config writes them: `physics.kinematics[]` items that name a
// `joint` (items describing only a link, such as {link: base, length_m: 0.1}, are not joints), or the arm
// driver's own `joints[]` block. The capability and the simulated driver read the same list, so they agree.
#pragma once

#include <rcand/sdk/plugin.hpp>

#include <optional>
#include <string>
#include <vector>

namespace rcand::plugins::arm {

struct JointLimit {
  static constexpr double kDefaultVelocityDps = 90.0;  // a hobby servo's no-load speed is 300-600 dps: 90 is gentle
  // The slowest speed a command may ask for. Slower looks stopped to an operator, servos cannot resolve it (a
  // Dynamixel X's velocity unit is 1.37 dps), and a speed near zero would turn every move into an endless one.
  static constexpr double kMinVelocityDps = 1.0;
  static constexpr double kDefaultStepDeg = 45.0;

  std::string joint;
  double min_deg = 0.0;
  double max_deg = 0.0;
  double max_velocity_dps = kDefaultVelocityDps;
  double max_step_deg = kDefaultStepDeg;  // the farthest one command may move this joint from where it is
  double home_deg = 0.0;                  // where a simulated joint starts; default 0 clamped into the range
};

// Parses `items` (a JSON array) found at `where` ("physics.kinematics", "drivers[arm0].joints"). Throws
// sdk::ConfigError naming the item and key ("physics.kinematics[1].max_deg: ...") on a wrong type, a missing
// bound, min >= max, a speed below kMinVelocityDps, a non-positive step, a home outside the range, or a duplicate
// joint.
std::vector<JointLimit> parse_joint_limits(const nlohmann::json& items, const std::string& where);

// The joints a robot config declares for the arm on driver `driver_id`: physics.kinematics when it names any
// joint, else that driver's `joints[]`. With no driver id, the first drivers[] entry that has `joints`.
// `where` is set to the key path the list came from. Empty when neither names a joint.
std::vector<JointLimit> joint_limits_from(const sdk::ConfigView& robot_config, const std::optional<std::string>& driver_id,
                                          std::string& where);

const JointLimit* find_joint(const std::vector<JointLimit>& joints, std::string_view name) noexcept;

}  // namespace rcand::plugins::arm
