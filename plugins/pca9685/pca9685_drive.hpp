// Driver protocol "pca9685" (alias "pca9685_i2c"): a differential drive on a PCA9685 PWM board over I2C. Every
// update is one auto-increment block write; halt() is one write (ALL_LED full off, or the whole channel table when an
// ESC needs its neutral pulse) plus the /OE pin when one is configured, and it returns by its deadline even when the
// bus is wedged. A board that does not answer is a named fault at start, never a silent mock.
//
// Hardware fail-safe: the PCA9685 has no watchdog, so if rcand dies the outputs keep their last value. The /OE pin
// (a GPIO wired to the board's OE input, pulled high on the board) is what turns them off without rcand: configure it.
#pragma once

#include <rcand/sdk/bus_worker.hpp>
#include <rcand/sdk/plugin.hpp>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "i2c_bus.hpp"
#include "motor_channels.hpp"
#include "output_pin.hpp"
#include "pca9685_registers.hpp"

namespace rcand::plugins::pca9685 {

using BusWorker = sdk::BusWorker<I2cBus>;

struct Pca9685Settings {
  std::string bus_path = "/dev/i2c-1";
  std::uint8_t address = 0x40;
  double frequency_hz = 50.0;
  double oscillator_hz = kInternalOscillatorHz;
  int prescale = 121;  // 50 Hz on 25 MHz
  MotorLayout motors;
  std::optional<std::string> oe_chip;
  std::optional<unsigned> oe_line;
  std::chrono::milliseconds halt_deadline{5};
  std::chrono::milliseconds command_timeout{50};
  std::chrono::milliseconds i2c_timeout{10};

  // From a drivers[] entry (port, address, channels, pwm_frequency_hz, oscillator_hz, oe_chip, oe_line, *_ms).
  // Throws sdk::ConfigError naming the key.
  static Pca9685Settings from(const sdk::ConfigView& config);
};

class Pca9685Drive final : public sdk::DifferentialDrive {
 public:
  // `oe` may be null (no /OE pin); when given it is high (outputs disabled) until start() has initialised the chip.
  Pca9685Drive(Pca9685Settings settings, std::shared_ptr<I2cBus> bus, std::unique_ptr<OutputPin> oe, sdk::Logger* log = nullptr);

  // Probes the address (the named no-ACK fault), runs the datasheet wake-up, checks PRE_SCALE reads back, sets the
  // motors stopped, then enables the outputs. Throws I2cError.
  void start() override;
  void set_wheel_speeds(double left, double right) override;
  void halt() noexcept override;
  void shutdown() noexcept override;  // halt, then the chip to sleep
  nlohmann::json status() const override;

  const Pca9685Settings& settings() const noexcept { return settings_; }
  std::uint64_t halts_unconfirmed() const;

 private:
  // Runs `job` on the bus worker; throws I2cError on failure or when `deadline` passes.
  void run(BusWorker::Job job, std::chrono::milliseconds deadline, const char* what);
  std::string fail_safe() const;

  const Pca9685Settings settings_;
  const std::shared_ptr<I2cBus> bus_;
  const std::shared_ptr<OutputPin> oe_;  // shared with queued jobs, which may outlive a call
  sdk::Logger* const log_;
  BusWorker worker_;

  // Bumped by every halt; a wheel update computed before a halt is not written after it. Shared with queued jobs.
  const std::shared_ptr<std::atomic<std::uint64_t>> generation_ = std::make_shared<std::atomic<std::uint64_t>>(0);
  // Orders "generation still current, so enable /OE" in a job against "new generation, disable /OE" in halt().
  const std::shared_ptr<std::mutex> oe_mutex_ = std::make_shared<std::mutex>();

  mutable std::mutex mutex_;  // the fields below; never held while waiting for the bus
  ChannelTable table_{};      // what the chip's LED registers hold (or are about to)
  double left_ = 0.0, right_ = 0.0;
  bool started_ = false;
  std::uint64_t commands_ = 0, halts_ = 0, halts_unconfirmed_ = 0;
  std::string last_error_;
};

}  // namespace rcand::plugins::pca9685
