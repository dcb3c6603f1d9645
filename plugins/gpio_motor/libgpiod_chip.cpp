#include "libgpiod_chip.hpp"

#include <gpiod.h>

#include <cerrno>
#include <cstring>

namespace rcand::plugins::gpio_motor {

namespace {

std::string errno_text(int error) {
  if (error == EBUSY) return "busy: another program holds it (gpioinfo shows which)";
  if (error == EACCES || error == EPERM) return "permission denied: add the rcand user to the gpio group";
  return std::strerror(error);
}

class LibgpiodLine final : public OutputLine {
 public:
  LibgpiodLine(gpiod_line* line, std::string name) : line_(line), name_(std::move(name)) {}
  ~LibgpiodLine() override { gpiod_line_release(line_); }
  bool set(bool active) noexcept override { return gpiod_line_set_value(line_, active ? 1 : 0) == 0; }
  std::string describe() const override { return name_; }

 private:
  gpiod_line* line_;
  std::string name_;
};

}  // namespace

std::unique_ptr<LibgpiodChip> LibgpiodChip::open(const std::optional<std::string>& selector,
                                                 const std::optional<std::string>& line_name) {
  if (selector) {
    if (gpiod_chip* chip = gpiod_chip_open_lookup(selector->c_str()))
      return std::unique_ptr<LibgpiodChip>(new LibgpiodChip(chip));
    const std::string error = errno_text(errno);
    throw GpioError("no GPIO chip '" + *selector + "' (tried it as a label, a name, a path and a number): " + error, *selector,
                    error, "gpiodetect lists the chips");
  }
  if (line_name) {
    if (gpiod_line* line = gpiod_line_find(line_name->c_str())) {
      // gpiod_line_find opened the line's chip for us: keep it, by reopening it under our ownership.
      const std::string name = gpiod_chip_name(gpiod_line_get_chip(line));
      gpiod_line_close_chip(line);
      if (gpiod_chip* chip = gpiod_chip_open_by_name(name.c_str())) return std::unique_ptr<LibgpiodChip>(new LibgpiodChip(chip));
    }
    throw GpioError("no GPIO chip has a line named \"" + *line_name + "\"; gpioinfo lists the line names, or set chip");
  }
  for (const auto& label : kDefaultChipLabels)
    if (gpiod_chip* chip = gpiod_chip_open_by_label(label.c_str())) return std::unique_ptr<LibgpiodChip>(new LibgpiodChip(chip));
  throw GpioError(
      "no GPIO chip labelled pinctrl-rp1, pinctrl-bcm2711 or pinctrl-bcm2835 (not a Raspberry Pi?): set chip "
      "to a label, name or path from gpiodetect");
}

LibgpiodChip::~LibgpiodChip() { gpiod_chip_close(chip_); }

std::string LibgpiodChip::describe() const { return std::string(gpiod_chip_name(chip_)) + " [" + gpiod_chip_label(chip_) + "]"; }

std::unique_ptr<OutputLine> LibgpiodChip::request_output(const LineRef& ref, bool active_low, const std::string& consumer) {
  gpiod_line* line = nullptr;
  if (const auto* offset = std::get_if<unsigned>(&ref)) {
    if (*offset >= gpiod_chip_num_lines(chip_))
      throw GpioError(describe() + " has no " + gpio_motor::describe(ref) + " (it has " +
                      std::to_string(gpiod_chip_num_lines(chip_)) + " lines)");
    line = gpiod_chip_get_line(chip_, *offset);
  } else {
    line = gpiod_chip_find_line(chip_, std::get<std::string>(ref).c_str());
  }
  if (!line) throw GpioError(describe() + " has no " + gpio_motor::describe(ref) + "; gpioinfo lists its lines");
  // Inactive from the first instant: the kernel applies ACTIVE_LOW and the default value in the same request.
  const int flags = active_low ? GPIOD_LINE_REQUEST_FLAG_ACTIVE_LOW : 0;
  if (gpiod_line_request_output_flags(line, consumer.c_str(), flags, 0) != 0)
    throw GpioError("cannot request " + gpio_motor::describe(ref) + " of " + describe() + " as an output: " + errno_text(errno));
  return std::make_unique<LibgpiodLine>(line, describe() + " " + gpio_motor::describe(ref) + (active_low ? " (active low)" : ""));
}

}  // namespace rcand::plugins::gpio_motor
