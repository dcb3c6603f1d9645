// A `protocol: dynamixel` drivers[] entry:
//   port: /dev/ttyUSB0          baud_rate: 1000000        watchdog_ms: 100       poll_hz: 50
//   servos:
//     - {id: 1, joint: shoulder, min_deg: -90, max_deg: 90}     # position mode, an arm joint
//     - {id: 11, wheel: left}                                    # velocity mode, a drive wheel
//     - {id: 12, wheel: right, reverse: true}
// A joint without min_deg/max_deg takes them from physics.kinematics (the item naming that joint), and in any case
// never beyond the servo's own Min/Max Position Limit read at start.
#pragma once

#include <rcand/sdk/config_view.hpp>

#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace rcand::plugins::dynamixel {

struct ServoSettings {
  enum class Role { Joint, LeftWheel, RightWheel };
  std::uint8_t id = 1;
  Role role = Role::Joint;
  std::string name;  // the joint name, or "left"/"right"
  std::optional<double> min_deg, max_deg;
  bool reverse = false;  // wheels: positive speed turns the servo the other way (a mirrored motor)
};

struct DynamixelSettings {
  std::string port;
  int baud_rate = 57600;  // the X-series factory default; 1000000 for a fast arm
  std::vector<ServoSettings> servos;
  std::chrono::milliseconds watchdog{100};  // 0: off (warned). Rounded up to the servo's 20 ms unit.
  double poll_hz = 50.0;
  std::chrono::milliseconds reply_timeout{20};  // beyond the wire time: covers a 16 ms latency timer
  std::chrono::milliseconds halt_deadline{5};
  std::chrono::milliseconds command_timeout{100};
  double joint_velocity_dps = 90.0;     // when a target names no speed
  std::optional<double> wheel_max_rpm;  // default: each wheel servo's Velocity Limit
  bool reboot_on_error = false;         // at start, reboot a servo that reports a hardware error instead of failing
  std::string sysfs_root = "/sys";

  bool has_wheels() const;
  bool has_joints() const;
  // The watchdog register value (20 ms units), 0 when off.
  std::uint8_t watchdog_units() const;

  // Throws sdk::ConfigError naming the key ("servos[2].id: ...").
  static DynamixelSettings from(const sdk::ConfigView& driver, const sdk::ConfigView& robot = {});
};

}  // namespace rcand::plugins::dynamixel
