// PwmOutput on /sys/class/pwm/pwmchip<N>/pwm<M> (Raspberry Pi: dtoverlay=pwm-2chan). Exported if it is not yet,
// period set from the frequency, duty 0, then enabled; the duty_cycle file stays open so a speed change is one
// write. Note that a sysfs PWM keeps running when its process dies: it is no fail-safe.
#pragma once

#include <string>

#include "pwm_output.hpp"

namespace rcand::plugins::gpio_motor {

class SysfsPwm final : public PwmOutput {
 public:
  // Throws GpioError naming the file and the fix (the overlay, the gpio group).
  SysfsPwm(unsigned chip, unsigned channel, double frequency_hz, const std::string& sysfs_root = "/sys");
  ~SysfsPwm() override;  // duty 0, disabled
  SysfsPwm(const SysfsPwm&) = delete;
  SysfsPwm& operator=(const SysfsPwm&) = delete;

  bool set_duty(double duty) noexcept override;
  std::string describe() const override { return dir_; }
  long long period_ns() const noexcept { return period_ns_; }

 private:
  std::string dir_;
  long long period_ns_;
  int duty_fd_ = -1;
};

}  // namespace rcand::plugins::gpio_motor
