// A PWM output for a bridge's speed input. The real one is the kernel's sysfs PWM class (sysfs_pwm.hpp); tests
// record duty changes in the fake chip's event log.
#pragma once

#include <string>

namespace rcand::plugins::gpio_motor {

class PwmOutput {
 public:
  virtual ~PwmOutput() = default;
  // `duty` in [0, 1]. False when the kernel refused the write.
  virtual bool set_duty(double duty) noexcept = 0;
  virtual std::string describe() const = 0;
};

}  // namespace rcand::plugins::gpio_motor
