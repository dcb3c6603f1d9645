// The GPIO lines an H-bridge needs, behind a small interface: the real backend is libgpiod 1.6 (libgpiod_chip.hpp),
// tests use a fake chip that records every level change (testing/fake_gpio.hpp). Values are logical ("active"):
// an active-low line is declared in the request itself, so the kernel inverts it from the first instant and a line
// that should start inactive never glitches active while it is being set up.
#pragma once

#include <memory>
#include <stdexcept>
#include <string>
#include <variant>

#include <rcand/sdk/device_fault.hpp>

namespace rcand::plugins::gpio_motor {

// A device fault (rcand/sdk/device_fault.hpp): the chip or file, the OS error and a hint where there is one.
class GpioError : public sdk::DeviceFault {
 public:
  using sdk::DeviceFault::DeviceFault;
};

// A line by offset on its chip (17) or by name ("GPIO17", as the Raspberry Pi's device tree names them).
using LineRef = std::variant<unsigned, std::string>;
std::string describe(const LineRef& line);

class OutputLine {
 public:
  virtual ~OutputLine() = default;
  // One ioctl; false when the kernel refused (the line stays as it was).
  virtual bool set(bool active) noexcept = 0;
  virtual std::string describe() const = 0;
};

class GpioChip {
 public:
  virtual ~GpioChip() = default;
  // Requests `line` as an output, inactive from the request on. Throws GpioError naming the chip and the line
  // (missing, busy: another program holds it, permission: the gpio group).
  virtual std::unique_ptr<OutputLine> request_output(const LineRef& line, bool active_low, const std::string& consumer) = 0;
  virtual std::string describe() const = 0;  // "gpiochip4 [pinctrl-rp1]"
};

}  // namespace rcand::plugins::gpio_motor
