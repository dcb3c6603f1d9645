// I2cBus over Linux i2c-dev: every transaction is one I2C_RDWR ioctl, so a block write is one START...STOP and a
// register read uses a repeated START. The adapter timeout is set so a wedged bus returns ETIMEDOUT instead of
// blocking for the adapter's default (1 s on many).
#pragma once

#include <chrono>

#include "i2c_bus.hpp"

namespace rcand::plugins::pca9685 {

class LinuxI2cBus final : public I2cBus {
 public:
  // Opens `path` ("/dev/i2c-1"). Throws I2cError(Io) naming the path and what to enable when it is missing.
  LinuxI2cBus(std::string path, std::chrono::milliseconds timeout);
  ~LinuxI2cBus() override;
  LinuxI2cBus(const LinuxI2cBus&) = delete;
  LinuxI2cBus& operator=(const LinuxI2cBus&) = delete;

  void write(std::uint8_t address, std::span<const std::uint8_t> bytes) override;
  void read(std::uint8_t address, std::uint8_t reg, std::span<std::uint8_t> out) override;
  std::string path() const override { return path_; }

 private:
  [[noreturn]] void fail(std::uint8_t address, int error, const char* what) const;

  const std::string path_;
  int fd_ = -1;
};

}  // namespace rcand::plugins::pca9685
