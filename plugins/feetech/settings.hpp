// A `protocol: feetech` drivers[] entry (manifests/feetech.json documents every key):
//   port: /dev/ttyACM0     baud_rate: 1000000     model: sts3215     poll_hz: 50
//   servos:
//     - {id: 1, joint: shoulder_pan, min_deg: -90, max_deg: 90, max_velocity_dps: 180, torque_limit_pct: 60}
//     - {id: 7, wheel: left}                                  # wheel (constant speed) mode, a drive wheel
//     - {id: 8, wheel: right, invert: true}
// A joint without min_deg/max_deg takes them from physics.kinematics (the item naming that joint as `joint` or `id`,
// with min_deg/max_deg or limits_deg: [lo, hi]), and in any case never beyond the servo's own angle limits read at
// start. A joint's angle is offset_deg + (ticks - 2048) * 360 / 4096, negated when `invert`.
#pragma once

#include <rcand/sdk/config_view.hpp>

#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace rcand::plugins::feetech {

struct FeetechServoSettings {
  enum class Role { Joint, LeftWheel, RightWheel };
  std::uint8_t id = 1;
  Role role = Role::Joint;
  std::string name;                  // the joint name, or "left"/"right"
  std::optional<std::string> model;  // expected model ("sts3215"); checked against the model number read at start
  std::optional<double> min_deg, max_deg;
  bool invert = false;                     // the joint angle (or wheel speed) grows the other way
  double offset_deg = 0.0;                 // the joint angle at the servo's centre (2048)
  std::optional<double> max_velocity_dps;  // the joint's speed cap
  double torque_limit_pct = 100.0;         // of the stall torque
};

struct FeetechSettings {
  std::string port;
  int baud_rate = 1000000;  // the STS factory default
  std::vector<FeetechServoSettings> servos;
  double poll_hz = 50.0;
  std::chrono::milliseconds reply_timeout{20};  // beyond the wire time: covers a 16 ms latency timer
  unsigned retries = 2;                         // a read/write/ping with no answer is sent again this often
  unsigned lost_after_polls = 3;                // status reads in a row without a servo's answer: a named fault
  std::chrono::milliseconds halt_deadline{5};
  std::chrono::milliseconds command_timeout{100};
  double joint_velocity_dps = 90.0;     // when a target names no speed
  std::optional<double> wheel_max_rpm;  // wheel speed at 1.0; default: the model's no-load speed

  bool has_wheels() const;
  bool has_joints() const;

  // Throws sdk::ConfigError naming the key ("servos[2].id: ...").
  static FeetechSettings from(const sdk::ConfigView& driver, const sdk::ConfigView& robot = {});
};

}  // namespace rcand::plugins::feetech
