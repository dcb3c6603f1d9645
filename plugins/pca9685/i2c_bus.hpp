// The I2C bus as the PCA9685 driver needs it: whole transactions only, so a register block is written in one
// START...STOP and nothing else on the bus can interleave. The real backend is Linux i2c-dev (linux_i2c_bus.hpp);
// tests use a register-map fake (fake_pca9685_bus.hpp).
#pragma once

#include <cstdint>
#include <span>
#include <stdexcept>
#include <string>
#include <utility>

#include <rcand/sdk/device_fault.hpp>

namespace rcand::plugins::pca9685 {

// A device fault (rcand/sdk/device_fault.hpp): opening the bus names the path, the OS error and a hint.
class I2cError : public sdk::DeviceFault {
 public:
  enum class Kind {
    NoAck,    // nothing answered at the address: no power, wrong address, wrong bus, loose cable
    Timeout,  // the transfer did not finish: a wedged bus (SDA held low) or a stretched clock
    Io,       // anything else (the device file is missing, permission, ...)
  };
  I2cError(Kind kind, const std::string& message, std::string device = {}, std::string os_error = {}, std::string hint = {})
      : sdk::DeviceFault(message, std::move(device), std::move(os_error), std::move(hint)), kind_(kind) {}
  Kind kind() const noexcept { return kind_; }

 private:
  Kind kind_;
};

// The fault a robot builder can act on: "no ACK at 0x40 on /dev/i2c-1: check power and address, try i2cdetect -y 1".
std::string no_ack_message(std::uint8_t address, const std::string& bus_path);
// "/dev/i2c-1" from a config `port`: a bus number ("1") or a path.
std::string i2c_device_path(const std::string& port);

class I2cBus {
 public:
  virtual ~I2cBus() = default;
  // One write transaction to `address`: bytes[0] is the first register, the rest its data (the chip auto-increments).
  // Throws I2cError.
  virtual void write(std::uint8_t address, std::span<const std::uint8_t> bytes) = 0;
  // One combined transaction: the register pointer, a repeated START, then out.size() bytes read. Throws I2cError.
  virtual void read(std::uint8_t address, std::uint8_t reg, std::span<std::uint8_t> out) = 0;
  // The device path ("/dev/i2c-1"), for messages.
  virtual std::string path() const = 0;
};

}  // namespace rcand::plugins::pca9685
