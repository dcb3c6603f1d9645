// One motor on an H-bridge driven by GPIO: two direction inputs (IN1, IN2), an optional enable line (ENA, STBY) and
// an optional PWM (on ENA/PWMA). The rules that keep the bridge safe live here, in the order lines change:
//   - IN1 and IN2 are never active together (on a bridge without its own interlock that is a short through a leg);
//   - a direction change first turns the enable and the PWM off, then releases the old input, then sets the new one;
//   - stop: enable and PWM off, then both inputs inactive (coast).
// Not thread-safe: the drive serialises calls.
#pragma once

#include <memory>
#include <string>

#include "gpio_chip.hpp"
#include "pwm_output.hpp"

namespace rcand::plugins::gpio_motor {

class HBridge {
 public:
  enum class Direction { None, Forward, Reverse };
  // `enable` and `pwm` may be null. Without a PWM, speed is on/off: any |speed| >= on_threshold is full speed.
  HBridge(std::string name, std::unique_ptr<OutputLine> in1, std::unique_ptr<OutputLine> in2, std::unique_ptr<OutputLine> enable,
          std::unique_ptr<PwmOutput> pwm, double on_threshold = 0.05);

  // `speed` in [-1, 1] (clamped; NaN is 0). Returns false if the kernel refused a line change; the bridge is then
  // stopped as far as the lines allow.
  bool set(double speed) noexcept;
  // Enable and PWM off, both inputs inactive.
  bool stop() noexcept;
  // Enable and PWM off only (the first step of stop(); halt does it for every motor before anything else).
  bool disable() noexcept;

  Direction direction() const noexcept { return direction_; }
  double duty() const noexcept { return duty_; }
  const std::string& name() const noexcept { return name_; }
  bool has_enable() const noexcept { return enable_ != nullptr; }
  bool has_pwm() const noexcept { return pwm_ != nullptr; }
  std::string describe() const;

 private:
  std::string name_;
  std::unique_ptr<OutputLine> in1_, in2_, enable_;
  std::unique_ptr<PwmOutput> pwm_;
  double on_threshold_;
  Direction direction_ = Direction::None;
  double duty_ = 0.0;
  bool powered_ = false;
};

}  // namespace rcand::plugins::gpio_motor
