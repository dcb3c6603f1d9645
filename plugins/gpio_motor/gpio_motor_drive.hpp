// Driver protocol "gpio": a differential drive on two GPIO H-bridges (L298N, TB6612, discrete MOSFET bridges).
// Each update and halt() is a handful of line ioctls done under one mutex (microseconds, no bus, no queue), so
// halt() never waits behind more than the few line changes of a command in progress, and the shoot-through rules
// of HBridge hold across threads.
//
// Hardware fail-safe: when rcand dies the kernel releases its lines; on a Raspberry Pi they fall back to inputs, so
// the bridge's enable input must have a pull-down (a pull-up when active-low) to switch the bridge off by itself.
// A sysfs PWM keeps running after its process dies and is no fail-safe on its own.
#pragma once

#include <rcand/sdk/plugin.hpp>

#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "gpio_chip.hpp"
#include "gpio_settings.hpp"
#include "hbridge.hpp"
#include "pwm_output.hpp"

namespace rcand::plugins::gpio_motor {

using PwmFactory = std::function<std::unique_ptr<PwmOutput>(const PwmSettings&)>;

class GpioMotorDrive final : public sdk::DifferentialDrive {
 public:
  GpioMotorDrive(GpioMotorSettings settings, std::shared_ptr<GpioChip> chip, PwmFactory pwm, sdk::Logger* log = nullptr);

  // Requests every line (inactive from the request on, active-low applied by the kernel) and opens the PWMs.
  // Throws GpioError naming the chip and line.
  void start() override;
  void set_wheel_speeds(double left, double right) override;
  void halt() noexcept override;
  void shutdown() noexcept override;  // halt, then the lines are released
  nlohmann::json status() const override;

  std::string fail_safe() const;

 private:
  std::unique_ptr<HBridge> make_bridge(const std::string& name, const MotorSettings& motor);

  const GpioMotorSettings settings_;
  const std::shared_ptr<GpioChip> chip_;
  const PwmFactory pwm_factory_;
  sdk::Logger* const log_;

  mutable std::mutex mutex_;  // the bridges: every line change happens under it
  std::unique_ptr<HBridge> left_, right_;
  std::unique_ptr<OutputLine> standby_;  // settings_.standby: active while a motor runs
  double left_speed_ = 0.0, right_speed_ = 0.0;
  std::uint64_t commands_ = 0, halts_ = 0, refused_ = 0;
  std::string last_error_;
};

}  // namespace rcand::plugins::gpio_motor
