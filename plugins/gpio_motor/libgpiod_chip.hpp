// GpioChip on libgpiod 1.6 (Debian 12's libgpiod-dev; the C API). Chip numbers move between kernels (a Raspberry
// Pi 5's header went from gpiochip4 to gpiochip0), so the chip is found by what does not move: a label, or the name
// of a line it carries, with a config override.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "gpio_chip.hpp"

struct gpiod_chip;

namespace rcand::plugins::gpio_motor {

// The labels of the Raspberry Pi header's chip, newest board first: tried when the config names no chip and no line
// by name.
inline const std::vector<std::string> kDefaultChipLabels{"pinctrl-rp1", "pinctrl-bcm2711", "pinctrl-bcm2835"};

class LibgpiodChip final : public GpioChip {
 public:
  // `selector`: a label ("pinctrl-rp1"), a name ("gpiochip4"), a path ("/dev/gpiochip4") or a number ("4"). Without
  // one, the chip carrying `line_name` (when given), else the first of kDefaultChipLabels present. Throws GpioError
  // saying what was tried and how to list the chips (gpiodetect, gpioinfo).
  static std::unique_ptr<LibgpiodChip> open(const std::optional<std::string>& selector,
                                            const std::optional<std::string>& line_name);
  ~LibgpiodChip() override;
  LibgpiodChip(const LibgpiodChip&) = delete;
  LibgpiodChip& operator=(const LibgpiodChip&) = delete;

  std::unique_ptr<OutputLine> request_output(const LineRef& line, bool active_low, const std::string& consumer) override;
  std::string describe() const override;

 private:
  explicit LibgpiodChip(gpiod_chip* chip) : chip_(chip) {}
  gpiod_chip* chip_;
};

}  // namespace rcand::plugins::gpio_motor
