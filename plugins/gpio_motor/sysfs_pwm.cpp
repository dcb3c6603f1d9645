#include "sysfs_pwm.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <thread>

#include "gpio_chip.hpp"

namespace rcand::plugins::gpio_motor {

namespace {

void write_file(const std::string& path, const std::string& value) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CLOEXEC);
  if (fd < 0 || ::write(fd, value.data(), value.size()) != static_cast<ssize_t>(value.size())) {
    const int error = errno;
    if (fd >= 0) ::close(fd);
    throw GpioError("cannot write " + value + " to " + path + ": " + std::strerror(error), path, std::strerror(error),
                    error == EACCES ? "add the rcand user to the gpio group, or a udev rule for the pwm class" : "");
  }
  ::close(fd);
}

}  // namespace

SysfsPwm::SysfsPwm(unsigned chip, unsigned channel, double frequency_hz, const std::string& sysfs_root) {
  if (!std::isfinite(frequency_hz) || frequency_hz < 1 || frequency_hz > 1e6)
    throw GpioError("pwm frequency " + std::to_string(frequency_hz) + " Hz: expected 1..1000000");
  period_ns_ = std::llround(1e9 / frequency_hz);
  const std::string chip_dir = sysfs_root + "/class/pwm/pwmchip" + std::to_string(chip);
  if (!std::filesystem::exists(chip_dir))
    throw GpioError("no " + chip_dir, chip_dir, "", "enable the PWM overlay (Raspberry Pi: dtoverlay=pwm-2chan in config.txt)");
  dir_ = chip_dir + "/pwm" + std::to_string(channel);
  if (!std::filesystem::exists(dir_)) {
    write_file(chip_dir + "/export", std::to_string(channel));
    // The kernel creates the directory at once; udev may take a moment to give it to the gpio group.
    for (int i = 0; i < 100 && ::access((dir_ + "/period").c_str(), W_OK) != 0; ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  write_file(dir_ + "/duty_cycle", "0");  // first: a period shorter than the old duty would be refused
  write_file(dir_ + "/period", std::to_string(period_ns_));
  write_file(dir_ + "/enable", "1");
  duty_fd_ = ::open((dir_ + "/duty_cycle").c_str(), O_WRONLY | O_CLOEXEC);
  if (duty_fd_ < 0) throw GpioError("cannot open " + dir_ + "/duty_cycle: " + std::strerror(errno));
}

SysfsPwm::~SysfsPwm() {
  set_duty(0.0);
  if (duty_fd_ >= 0) ::close(duty_fd_);
  try {
    write_file(dir_ + "/enable", "0");
  } catch (const GpioError&) {
  }
}

bool SysfsPwm::set_duty(double duty) noexcept {
  if (!std::isfinite(duty)) duty = 0.0;
  const long long ns = std::llround(std::clamp(duty, 0.0, 1.0) * static_cast<double>(period_ns_));
  const std::string text = std::to_string(ns);
  return ::pwrite(duty_fd_, text.data(), text.size(), 0) == static_cast<ssize_t>(text.size());
}

}  // namespace rcand::plugins::gpio_motor
