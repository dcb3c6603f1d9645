// A `protocol: gpio` drivers[] entry: a differential drive on two GPIO H-bridges.
//   chip: pinctrl-rp1            # optional: label, name, path or number; default: found (see libgpiod_chip.hpp)
//   channels:
//     left:  {in1: 17, in2: 27, enable: 22}                       # lines by offset...
//     right: {in1: GPIO23, in2: GPIO24, enable: {line: 25, active_low: true},
//             pwm: {chip: 0, channel: 1, frequency_hz: 1000}}     # ...or by name; PWM through /sys/class/pwm
//   standby: 19                  # optional: a bridge chip's STBY input shared by both motors (TB6612)
#pragma once

#include <rcand/sdk/config_view.hpp>

#include <optional>
#include <string>

#include "gpio_chip.hpp"

namespace rcand::plugins::gpio_motor {

struct LineSettings {
  LineRef line;
  bool active_low = false;
};

struct PwmSettings {
  unsigned chip = 0;
  unsigned channel = 0;
  double frequency_hz = 1000.0;
};

struct MotorSettings {
  LineSettings in1, in2;
  std::optional<LineSettings> enable;
  std::optional<PwmSettings> pwm;
  bool reverse = false;  // the motor is mounted mirrored: positive speed drives IN2
};

struct GpioMotorSettings {
  std::optional<std::string> chip;
  MotorSettings left, right;
  // A standby input both motors share (a TB6612's STBY): active while a motor runs, inactive at every stop.
  std::optional<LineSettings> standby;
  std::string sysfs_root = "/sys";

  // The first line given by name, used to find the chip when none is configured.
  std::optional<std::string> first_line_name() const;
  // Throws sdk::ConfigError naming the key ("channels.left.in2: ...").
  static GpioMotorSettings from(const sdk::ConfigView& config);
};

}  // namespace rcand::plugins::gpio_motor
