#include "pca9685_drive.hpp"

#include <cmath>
#include <cstdio>
#include <thread>

namespace rcand::plugins::pca9685 {

namespace {

using nlohmann::json;

std::string hex(std::uint8_t value) {
  char text[8];
  std::snprintf(text, sizeof text, "0x%02x", value);
  return text;
}

// `address`: 0x40 in YAML is the integer 64; "0x40" as a string is accepted too. 7-bit addresses 0x03..0x77.
std::uint8_t read_address(const json& config) {
  const auto it = config.find("address");
  if (it == config.end() || it->is_null()) return 0x40;
  long long value = -1;
  if (it->is_number_integer()) value = it->get<long long>();
  else if (it->is_string()) {
    const std::string text = it->get<std::string>();
    try {
      std::size_t used = 0;
      value = std::stoll(text, &used, 0);
      if (used != text.size()) value = -1;
    } catch (const std::exception&) {
      value = -1;
    }
  }
  if (value < 0x03 || value > 0x77)
    throw sdk::ConfigError("address: expected a 7-bit I2C address 0x03..0x77 (the board's default is 0x40), found " + it->dump());
  return static_cast<std::uint8_t>(value);
}

std::string read_port(const json& config) {
  const auto it = config.find("port");
  if (it == config.end() || it->is_null()) return "/dev/i2c-1";
  if (it->is_number_integer() && it->get<long long>() >= 0) return "/dev/i2c-" + std::to_string(it->get<long long>());
  if (it->is_string() && !it->get<std::string>().empty()) return i2c_device_path(it->get<std::string>());
  throw sdk::ConfigError("port: expected an I2C bus number (1) or a device path (/dev/i2c-1), found " + it->dump());
}

std::chrono::milliseconds read_ms(const sdk::ConfigView& config, const char* key, long long fallback, long long min,
                                  long long max) {
  const long long value = config.get<long long>(key).value_or(fallback);
  if (value < min || value > max)
    throw sdk::ConfigError(std::string(key) + ": expected an integer in [" + std::to_string(min) + ", " + std::to_string(max) +
                           "], found " + std::to_string(value));
  return std::chrono::milliseconds(value);
}

}  // namespace

Pca9685Settings Pca9685Settings::from(const sdk::ConfigView& config) {
  Pca9685Settings s;
  const json& raw = config.raw();
  s.bus_path = read_port(raw);
  s.address = read_address(raw);
  s.frequency_hz = config.get<double>("pwm_frequency_hz").value_or(s.frequency_hz);
  s.oscillator_hz = config.get<double>("oscillator_hz").value_or(s.oscillator_hz);
  if (!std::isfinite(s.oscillator_hz) || s.oscillator_hz < 1e6 || s.oscillator_hz > 50e6)
    throw sdk::ConfigError("oscillator_hz: expected 1000000..50000000 (25000000 is the internal oscillator), found " +
                           json(s.oscillator_hz).dump());
  const auto prescale = prescale_for(s.frequency_hz, s.oscillator_hz);
  if (!prescale)
    throw sdk::ConfigError("pwm_frequency_hz: " + json(s.frequency_hz).dump() + " Hz is outside what the chip can do with a " +
                           json(s.oscillator_hz).dump() + " Hz oscillator (" +
                           json(frequency_of(kMaxPrescale, s.oscillator_hz)).dump() + ".." +
                           json(frequency_of(kMinPrescale, s.oscillator_hz)).dump() + " Hz)");
  s.prescale = *prescale;
  s.motors = parse_motor_layout(raw.contains("channels") ? raw["channels"] : json());
  // An ESC's pulse must fit in the PWM period: a longer one is a constant high (full on), which is no pulse at all,
  // so the neutral that halt() writes would stop nothing.
  const double period_us = 1e6 / frequency_of(s.prescale, s.oscillator_hz);
  for (const auto& [side, motor] : {std::pair{"left", &s.motors.left}, std::pair{"right", &s.motors.right}})
    if (motor->kind == Motor::Kind::Esc && motor->max_us >= period_us)
      throw sdk::ConfigError("pwm_frequency_hz: " + json(s.frequency_hz).dump() + " Hz gives a period of " +
                             std::to_string(static_cast<long long>(period_us)) + " us, too short for the pulses of channels." +
                             side + " (up to max_us " + json(motor->max_us).dump() +
                             " us): an ESC or servo needs 50..400 Hz (the default is 50)");
  s.oe_chip = config.get<std::string>("oe_chip");
  if (const auto line = config.get<long long>("oe_line")) {
    if (*line < 0 || *line > 1023)
      throw sdk::ConfigError("oe_line: expected a GPIO line offset 0..1023, found " + std::to_string(*line));
    s.oe_line = static_cast<unsigned>(*line);
    if (!s.oe_chip) s.oe_chip = "/dev/gpiochip0";
  } else if (s.oe_chip) {
    throw sdk::ConfigError("oe_line: required with oe_chip (the GPIO line wired to the board's OE pin)");
  }
  s.halt_deadline = read_ms(config, "halt_deadline_ms", 5, 1, 100);
  s.command_timeout = read_ms(config, "command_timeout_ms", 50, 1, 1000);
  s.i2c_timeout = read_ms(config, "i2c_timeout_ms", 10, 10, 1000);
  return s;
}

Pca9685Drive::Pca9685Drive(Pca9685Settings settings, std::shared_ptr<I2cBus> bus, std::unique_ptr<OutputPin> oe, sdk::Logger* log)
    : settings_(std::move(settings)), bus_(std::move(bus)), oe_(std::move(oe)), log_(log), worker_(bus_) {
  for (auto& channel : table_) channel = ChannelCounts::full_off();
  settings_.motors.left.stop(table_, settings_.prescale, settings_.oscillator_hz);
  settings_.motors.right.stop(table_, settings_.prescale, settings_.oscillator_hz);
}

void Pca9685Drive::run(BusWorker::Job job, std::chrono::milliseconds deadline, const char* what) {
  const auto result = worker_.run(std::move(job), deadline);
  switch (result.outcome) {
    case BusWorker::Outcome::Done: return;
    case BusWorker::Outcome::Failed: std::rethrow_exception(result.error);
    case BusWorker::Outcome::Dropped: return;  // a halt superseded it: that is the state the motors should be in
    case BusWorker::Outcome::TimedOut:
      throw I2cError(I2cError::Kind::Timeout, std::string(what) + ": no answer from " + hex(settings_.address) + " on " +
                                                  bus_->path() + " within " + std::to_string(deadline.count()) +
                                                  " ms: the bus may be wedged (SDA held low); power-cycle the board");
  }
}

void Pca9685Drive::start() {
  const std::uint8_t address = settings_.address;
  const int prescale = settings_.prescale;
  std::vector<std::uint8_t> stopped;
  {
    std::lock_guard lock(mutex_);
    stopped = channel_block(table_, 0, kChannels - 1);
  }
  const auto deadline = std::max(settings_.command_timeout, std::chrono::milliseconds(500));
  run(
      [=](I2cBus& bus) {
        std::uint8_t mode1 = 0;
        bus.read(address, reg::kMode1, {&mode1, 1});  // the probe: a missing board fails here, by name
        for (const auto& block : wake_sequence(prescale)) bus.write(address, block);
        std::this_thread::sleep_for(std::chrono::microseconds(500));  // the oscillator's start-up (datasheet 7.3.1.1)
        bus.write(address, restart_block());
        std::uint8_t readback = 0;
        bus.read(address, reg::kPreScale, {&readback, 1});
        if (readback != prescale)
          throw I2cError(I2cError::Kind::Io, "the device at " + hex(address) + " on " + bus.path() +
                                                 " did not keep PRE_SCALE (wrote " + std::to_string(prescale) + ", read " +
                                                 std::to_string(readback) + "): is it a PCA9685?");
        bus.write(address, stopped);  // ESCs arm on their neutral pulse; bridges stay off
      },
      deadline, "start");
  if (oe_ && !oe_->set(false)) throw I2cError(I2cError::Kind::Io, "cannot enable the outputs on /OE (" + oe_->describe() + ")");
  std::lock_guard lock(mutex_);
  started_ = true;
  if (log_)
    log_->info("pca9685 at ", hex(address), " on ", bus_->path(), ": ", frequency_of(prescale, settings_.oscillator_hz),
               " Hz (prescale ", prescale, "); ", fail_safe());
}

void Pca9685Drive::set_wheel_speeds(double left, double right) {
  std::vector<std::uint8_t> block;
  std::uint64_t generation = 0;
  {
    std::lock_guard lock(mutex_);
    if (!started_) throw I2cError(I2cError::Kind::Io, "pca9685: not started");
    settings_.motors.left.apply(left, table_, settings_.prescale, settings_.oscillator_hz);
    settings_.motors.right.apply(right, table_, settings_.prescale, settings_.oscillator_hz);
    const auto [first, last] = settings_.motors.span();
    block = channel_block(table_, first, last);
    left_ = std::isfinite(left) ? std::clamp(left, -1.0, 1.0) : 0.0;
    right_ = std::isfinite(right) ? std::clamp(right, -1.0, 1.0) : 0.0;
    ++commands_;
    generation = generation_->load();
  }
  run(
      [address = settings_.address, block = std::move(block), generation, current = generation_, oe = oe_,
       oe_mutex = oe_mutex_](I2cBus& bus) {
        if (current->load() != generation) return;  // a halt came first: this update is stale
        bus.write(address, block);
        if (!oe) return;
        std::lock_guard order(*oe_mutex);
        if (current->load() == generation) oe->set(false);  // outputs back on after a halt, unless another halt came
      },
      settings_.command_timeout, "wheel update");
}

void Pca9685Drive::halt() noexcept {
  try {
    std::vector<std::uint8_t> block;
    {
      std::lock_guard order(*oe_mutex_);
      generation_->fetch_add(1);
      if (oe_) oe_->set(true);  // hardware off first: works even when the bus does not
    }
    {
      std::lock_guard lock(mutex_);
      settings_.motors.left.stop(table_, settings_.prescale, settings_.oscillator_hz);
      settings_.motors.right.stop(table_, settings_.prescale, settings_.oscillator_hz);
      // One transaction either way: ALL_LED full off, or every channel when an ESC needs its neutral pulse.
      block = settings_.motors.any_esc() ? channel_block(table_, 0, kChannels - 1) : all_off_block();
      left_ = right_ = 0.0;
      ++halts_;
    }
    const auto result =
        worker_.urgent([address = settings_.address, block = std::move(block)](I2cBus& bus) { bus.write(address, block); },
                       settings_.halt_deadline);
    if (result.outcome == BusWorker::Outcome::Done) return;
    std::string why = result.outcome == BusWorker::Outcome::TimedOut
                          ? "not confirmed within " + std::to_string(settings_.halt_deadline.count()) + " ms (bus busy or wedged)"
                          : "failed on the bus";
    if (result.error) try {
        std::rethrow_exception(result.error);
      } catch (const std::exception& e) {
        why += std::string(": ") + e.what();
      }
    why += oe_ ? "; outputs disabled by /OE" : "; no /OE pin configured: the motors may still run";
    {
      std::lock_guard lock(mutex_);
      ++halts_unconfirmed_;
      last_error_ = "halt " + why;
    }
    if (log_) log_->error("pca9685 halt ", why);
  } catch (...) {  // allocation only; /OE (when configured) is already high
  }
}

void Pca9685Drive::shutdown() noexcept {
  halt();
  try {
    // Asleep, the oscillator stops and no output toggles until the next start.
    (void)worker_.run(
        [address = settings_.address](I2cBus& bus) {
          const std::uint8_t sleep[] = {reg::kMode1, reg::kMode1Sleep | reg::kMode1Ai};
          bus.write(address, sleep);
        },
        std::chrono::milliseconds(100));
  } catch (...) {
  }
}

std::string Pca9685Drive::fail_safe() const {
  if (oe_)
    return "fail-safe: halt = all outputs off in one I2C write and /OE (" + oe_->describe() +
           ") high; the board's OE pull-up turns the outputs off if rcand dies";
  return "fail-safe: halt = all outputs off in one I2C write; NO /OE pin configured: the PCA9685 has no watchdog, so if rcand "
         "dies the "
         "outputs keep their last value (set oe_line)";
}

std::uint64_t Pca9685Drive::halts_unconfirmed() const {
  std::lock_guard lock(mutex_);
  return halts_unconfirmed_;
}

nlohmann::json Pca9685Drive::status() const {
  std::lock_guard lock(mutex_);
  return {{"bus", bus_->path()},
          {"address", hex(settings_.address)},
          {"pwm_frequency_hz", frequency_of(settings_.prescale, settings_.oscillator_hz)},
          {"prescale", settings_.prescale},
          {"started", started_},
          {"left", left_},
          {"right", right_},
          {"commands", commands_},
          {"halts", halts_},
          {"halts_unconfirmed", halts_unconfirmed_},
          {"last_error", last_error_.empty() ? json(nullptr) : json(last_error_)},
          {"oe_pin", oe_ ? json(oe_->describe()) : json(nullptr)},
          {"fail_safe", fail_safe()}};
}

}  // namespace rcand::plugins::pca9685
