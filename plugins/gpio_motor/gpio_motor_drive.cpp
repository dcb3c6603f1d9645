#include "gpio_motor_drive.hpp"

#include <cmath>

namespace rcand::plugins::gpio_motor {

namespace {

const char* direction_name(HBridge::Direction d) {
  switch (d) {
    case HBridge::Direction::Forward: return "forward";
    case HBridge::Direction::Reverse: return "reverse";
    case HBridge::Direction::None: break;
  }
  return "stopped";
}

}  // namespace

GpioMotorDrive::GpioMotorDrive(GpioMotorSettings settings, std::shared_ptr<GpioChip> chip, PwmFactory pwm, sdk::Logger* log)
    : settings_(std::move(settings)), chip_(std::move(chip)), pwm_factory_(std::move(pwm)), log_(log) {}

std::unique_ptr<HBridge> GpioMotorDrive::make_bridge(const std::string& name, const MotorSettings& m) {
  const std::string consumer = "rcand-" + name;
  // Requested in the order that keeps the bridge off: the enable first, then the inputs; each inactive from its request.
  auto enable = m.enable ? chip_->request_output(m.enable->line, m.enable->active_low, consumer + "-en") : nullptr;
  auto in1 = chip_->request_output(m.in1.line, m.in1.active_low, consumer + "-in1");
  auto in2 = chip_->request_output(m.in2.line, m.in2.active_low, consumer + "-in2");
  std::unique_ptr<PwmOutput> pwm;
  if (m.pwm) {
    if (!pwm_factory_) throw GpioError(name + ": a PWM is configured but none is available");
    pwm = pwm_factory_(*m.pwm);
  }
  return std::make_unique<HBridge>(name, std::move(in1), std::move(in2), std::move(enable), std::move(pwm));
}

void GpioMotorDrive::start() {
  // The shared standby first and inactive: both bridges stay off while their lines are set up.
  auto standby = settings_.standby
                     ? chip_->request_output(settings_.standby->line, settings_.standby->active_low, "rcand-standby")
                     : nullptr;
  auto left = make_bridge("left", settings_.left);
  auto right = make_bridge("right", settings_.right);
  left->stop();
  right->stop();
  {
    std::lock_guard lock(mutex_);
    standby_ = std::move(standby);
    left_ = std::move(left);
    right_ = std::move(right);
  }
  if (log_) {
    log_->info("gpio drive on ", chip_->describe(), ": ", left_->describe(), "; ", right_->describe());
    log_->info("gpio drive: ", fail_safe());
    if (!settings_.left.enable || !settings_.right.enable)
      log_->warn("gpio drive: a motor has no enable line: nothing but the lines' release stops it if rcand dies");
  }
}

void GpioMotorDrive::set_wheel_speeds(double left, double right) {
  std::lock_guard lock(mutex_);
  if (!left_) throw GpioError("gpio drive: not started");
  ++commands_;
  left_speed_ = std::isfinite(left) ? std::clamp(left, -1.0, 1.0) : 0.0;
  right_speed_ = std::isfinite(right) ? std::clamp(right, -1.0, 1.0) : 0.0;
  // A mirrored motor turns the other way for the same speed.
  const bool running = left_speed_ != 0.0 || right_speed_ != 0.0;
  // Standby goes inactive before a stop and active only once both bridges have their new inputs.
  bool ok_standby = running || !standby_ || standby_->set(false);
  const bool ok_left = left_->set(settings_.left.reverse ? -left_speed_ : left_speed_);
  const bool ok_right = right_->set(settings_.right.reverse ? -right_speed_ : right_speed_);
  if (ok_left && ok_right && running && standby_) ok_standby = standby_->set(true);
  if (ok_left && ok_right && ok_standby) return;
  ++refused_;
  if (standby_) standby_->set(false);
  left_->stop();
  right_->stop();
  left_speed_ = right_speed_ = 0.0;
  last_error_ = std::string("the kernel refused a line change on the ") +
                (!ok_left    ? "left bridge"
                 : !ok_right ? "right bridge"
                             : "standby line") +
                "; both motors stopped";
  throw GpioError("gpio drive: " + last_error_);
}

void GpioMotorDrive::halt() noexcept {
  std::lock_guard lock(mutex_);
  ++halts_;
  left_speed_ = right_speed_ = 0.0;
  if (!left_) return;
  // Power off both bridges before releasing any input, so the second motor is not left running while the first stops.
  bool ok = !standby_ || standby_->set(false);
  ok &= left_->disable();
  ok &= right_->disable();
  ok &= left_->stop();
  ok &= right_->stop();
  if (!ok) {
    ++refused_;
    last_error_ = "halt: the kernel refused a line change";
    if (log_) log_->error("gpio drive ", last_error_);
  }
}

void GpioMotorDrive::shutdown() noexcept {
  halt();
  std::lock_guard lock(mutex_);
  left_.reset();  // releases the lines (and disables the PWM)
  right_.reset();
  standby_.reset();
}

std::string GpioMotorDrive::fail_safe() const {
  std::string text =
      "fail-safe: halt = enable and PWM off, then both bridge inputs inactive; if rcand dies the kernel releases "
      "the lines (inputs again on a Raspberry Pi): a pull-down on each enable input (pull-up if active-low) "
      "switches the bridge off";
  if (settings_.standby) text += "; the shared standby line goes inactive first, and needs the same pull-down";
  if (!settings_.left.enable || !settings_.right.enable) text += "; WARNING: a motor has no enable line configured";
  if (settings_.left.pwm || settings_.right.pwm) text += "; note: a sysfs PWM keeps running after rcand dies";
  return text;
}

nlohmann::json GpioMotorDrive::status() const {
  std::lock_guard lock(mutex_);
  nlohmann::json motors = nlohmann::json::object();
  for (const auto* bridge : {left_.get(), right_.get()})
    if (bridge) motors[bridge->name()] = {{"direction", direction_name(bridge->direction())}, {"duty", bridge->duty()}};
  return {{"chip", chip_->describe()},
          {"started", left_ != nullptr},
          {"left", left_speed_},
          {"right", right_speed_},
          {"motors", std::move(motors)},
          {"commands", commands_},
          {"halts", halts_},
          {"refused", refused_},
          {"last_error", last_error_.empty() ? nlohmann::json(nullptr) : nlohmann::json(last_error_)},
          {"fail_safe", fail_safe()}};
}

}  // namespace rcand::plugins::gpio_motor
