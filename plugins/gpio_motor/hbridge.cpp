#include "hbridge.hpp"

#include <algorithm>
#include <cmath>

namespace rcand::plugins::gpio_motor {

HBridge::HBridge(std::string name, std::unique_ptr<OutputLine> in1, std::unique_ptr<OutputLine> in2,
                 std::unique_ptr<OutputLine> enable, std::unique_ptr<PwmOutput> pwm, double on_threshold)
    : name_(std::move(name)),
      in1_(std::move(in1)),
      in2_(std::move(in2)),
      enable_(std::move(enable)),
      pwm_(std::move(pwm)),
      on_threshold_(on_threshold) {}

bool HBridge::disable() noexcept {
  bool ok = true;
  if (enable_) ok &= enable_->set(false);
  if (pwm_) ok &= pwm_->set_duty(0.0);
  powered_ = false;
  duty_ = 0.0;
  return ok;
}

bool HBridge::stop() noexcept {
  bool ok = disable();
  ok &= in1_->set(false);
  ok &= in2_->set(false);
  direction_ = Direction::None;
  return ok;
}

bool HBridge::set(double speed) noexcept {
  if (!std::isfinite(speed)) speed = 0.0;
  speed = std::clamp(speed, -1.0, 1.0);
  const double magnitude = std::abs(speed);
  const bool on = pwm_ ? magnitude > 0.0 : magnitude >= on_threshold_;
  const Direction wanted = !on ? Direction::None : speed > 0 ? Direction::Forward : Direction::Reverse;
  if (wanted == Direction::None) return stop();

  if (wanted != direction_) {
    // Power off before touching the inputs, and release the old input before setting the new one: at no instant
    // are both inputs active, and the bridge never switches direction under load.
    bool ok = disable();
    OutputLine& release = wanted == Direction::Forward ? *in2_ : *in1_;
    OutputLine& drive = wanted == Direction::Forward ? *in1_ : *in2_;
    ok &= release.set(false);
    direction_ = Direction::None;
    if (!ok) {  // the old input may still be active: never add the other one to it
      stop();
      return false;
    }
    if (!drive.set(true)) {
      stop();
      return false;
    }
    direction_ = wanted;
  }
  const double duty = pwm_ ? magnitude : 1.0;
  bool ok = true;
  if (pwm_ && duty != duty_) ok &= pwm_->set_duty(duty);
  if (enable_ && !powered_) ok &= enable_->set(true);
  powered_ = true;
  duty_ = duty;
  if (!ok) {
    stop();
    return false;
  }
  return true;
}

std::string HBridge::describe() const {
  std::string text = name_ + ": IN1 " + in1_->describe() + ", IN2 " + in2_->describe();
  if (enable_) text += ", EN " + enable_->describe();
  if (pwm_) text += ", PWM " + pwm_->describe();
  return text;
}

}  // namespace rcand::plugins::gpio_motor
