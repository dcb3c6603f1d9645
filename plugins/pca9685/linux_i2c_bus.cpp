#include "linux_i2c_bus.hpp"

#include <fcntl.h>
#include <linux/i2c-dev.h>
#include <linux/i2c.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <vector>

namespace rcand::plugins::pca9685 {

std::string no_ack_message(std::uint8_t address, const std::string& bus_path) {
  char hex[8];
  std::snprintf(hex, sizeof hex, "0x%02x", address);
  std::string bus_number = bus_path;
  if (const auto dash = bus_path.rfind('-'); dash != std::string::npos) bus_number = bus_path.substr(dash + 1);
  return std::string("no ACK at ") + hex + " on " + bus_path + ": check power and address, try i2cdetect -y " + bus_number;
}

std::string i2c_device_path(const std::string& port) {
  const bool number = !port.empty() && port.find_first_not_of("0123456789") == std::string::npos;
  return number ? "/dev/i2c-" + port : port;
}

LinuxI2cBus::LinuxI2cBus(std::string path, std::chrono::milliseconds timeout) : path_(std::move(path)) {
  fd_ = ::open(path_.c_str(), O_RDWR | O_CLOEXEC);
  if (fd_ < 0) {
    const int error = errno;
    std::string hint = error == ENOENT   ? "enable I2C: dtparam=i2c_arm=on on a Raspberry Pi, then modprobe i2c-dev"
                       : error == EACCES ? "add the rcand user to the i2c group"
                                         : "";
    throw I2cError(I2cError::Kind::Io, "cannot open " + path_ + ": " + std::strerror(error), path_, std::strerror(error), hint);
  }
  // I2C_TIMEOUT is in units of 10 ms; at least one unit. No retries: a retry doubles the time a halt may wait.
  const unsigned long units = static_cast<unsigned long>(std::max<long long>(1, (timeout.count() + 9) / 10));
  (void)::ioctl(fd_, I2C_TIMEOUT, units);
  (void)::ioctl(fd_, I2C_RETRIES, 0UL);
}

LinuxI2cBus::~LinuxI2cBus() {
  if (fd_ >= 0) ::close(fd_);
}

void LinuxI2cBus::fail(std::uint8_t address, int error, const char* what) const {
  // Adapters disagree on how they report a NACK: bcm2835 says EREMOTEIO, i2c-gpio ENXIO, some EIO.
  if (error == ENXIO || error == EREMOTEIO || error == EIO)
    throw I2cError(I2cError::Kind::NoAck, no_ack_message(address, path_), path_, std::strerror(error));
  if (error == ETIMEDOUT || error == EAGAIN)
    throw I2cError(I2cError::Kind::Timeout,
                   std::string(what) + " on " + path_ + " timed out: the bus may be wedged (SDA held low)");
  throw I2cError(I2cError::Kind::Io, std::string(what) + " on " + path_ + ": " + std::strerror(error));
}

void LinuxI2cBus::write(std::uint8_t address, std::span<const std::uint8_t> bytes) {
  std::vector<std::uint8_t> buffer(bytes.begin(), bytes.end());  // i2c_msg wants a mutable buffer
  i2c_msg message{address, 0, static_cast<__u16>(buffer.size()), buffer.data()};
  i2c_rdwr_ioctl_data transfer{&message, 1};
  if (::ioctl(fd_, I2C_RDWR, &transfer) < 0) fail(address, errno, "write");
}

void LinuxI2cBus::read(std::uint8_t address, std::uint8_t reg, std::span<std::uint8_t> out) {
  i2c_msg messages[2] = {{address, 0, 1, &reg}, {address, I2C_M_RD, static_cast<__u16>(out.size()), out.data()}};
  i2c_rdwr_ioctl_data transfer{messages, 2};
  if (::ioctl(fd_, I2C_RDWR, &transfer) < 0) fail(address, errno, "read");
}

}  // namespace rcand::plugins::pca9685
