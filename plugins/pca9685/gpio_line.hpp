// OutputPin on the Linux GPIO character device (the kernel's v1 line-handle ioctls, <linux/gpio.h>): one line,
// requested as an output with its initial level set in the same request, so it never glitches low on open.
#pragma once

#include "output_pin.hpp"

namespace rcand::plugins::pca9685 {

class GpioLine final : public OutputPin {
 public:
  // Throws std::runtime_error naming the chip and line when the request fails (busy, missing, permission).
  GpioLine(std::string chip_path, unsigned line, bool initial_high);
  ~GpioLine() override;
  GpioLine(const GpioLine&) = delete;
  GpioLine& operator=(const GpioLine&) = delete;

  bool set(bool high) noexcept override;
  std::string describe() const override;

 private:
  const std::string chip_path_;
  const unsigned line_;
  int fd_ = -1;  // the line handle
};

}  // namespace rcand::plugins::pca9685
