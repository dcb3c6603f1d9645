// A GPIO output, here the PCA9685's active-low /OE pin: high disables every output in hardware, whatever the
// chip's registers hold, so it still works when the I2C bus does not.
#pragma once

#include <string>

namespace rcand::plugins::pca9685 {

class OutputPin {
 public:
  virtual ~OutputPin() = default;
  // Any thread, never blocks (one ioctl on a GPIO line). Returns false when the kernel refused the write.
  virtual bool set(bool high) noexcept = 0;
  virtual std::string describe() const = 0;  // "/dev/gpiochip0 line 17"
};

}  // namespace rcand::plugins::pca9685
