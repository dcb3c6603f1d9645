#include "gpio_line.hpp"

#include <fcntl.h>
#include <linux/gpio.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

#include <rcand/sdk/device_fault.hpp>

namespace rcand::plugins::pca9685 {

GpioLine::GpioLine(std::string chip_path, unsigned line, bool initial_high) : chip_path_(std::move(chip_path)), line_(line) {
  const int chip = ::open(chip_path_.c_str(), O_RDWR | O_CLOEXEC);
  if (chip < 0) {
    const int error = errno;
    throw sdk::DeviceFault("cannot open " + chip_path_ + ": " + std::strerror(error), chip_path_, std::strerror(error),
                           error == EACCES ? "add the rcand user to the gpio group" : "gpiodetect lists the GPIO chips");
  }
  gpiohandle_request request{};
  request.lineoffsets[0] = line_;
  request.lines = 1;
  request.flags = GPIOHANDLE_REQUEST_OUTPUT;
  request.default_values[0] = initial_high ? 1 : 0;
  std::strncpy(request.consumer_label, "rcand-pca9685-oe", sizeof request.consumer_label - 1);
  const int result = ::ioctl(chip, GPIO_GET_LINEHANDLE_IOCTL, &request);
  const int error = errno;
  ::close(chip);
  if (result < 0) throw std::runtime_error("cannot request " + describe() + " as an output: " + std::strerror(error));
  fd_ = request.fd;
}

GpioLine::~GpioLine() {
  if (fd_ >= 0) ::close(fd_);
}

bool GpioLine::set(bool high) noexcept {
  gpiohandle_data data{};
  data.values[0] = high ? 1 : 0;
  return ::ioctl(fd_, GPIOHANDLE_SET_LINE_VALUES_IOCTL, &data) == 0;
}

std::string GpioLine::describe() const { return chip_path_ + " line " + std::to_string(line_); }

}  // namespace rcand::plugins::pca9685
