// SerialLink on a Linux tty through termios: raw 8N1, no flow control, the baud rate set with termios2 (BOTHER) so
// that every rate the servos support (57600 .. 4.5 Mbps) is exact. Non-blocking I/O with poll(), plus an eventfd
// for interrupt().
#pragma once

#include "serial_link.hpp"

namespace rcand::plugins::dynamixel {

class PosixSerial final : public SerialLink {
 public:
  // Throws SerialError naming the path: missing device, permission (the dialout group), not a tty.
  PosixSerial(std::string path, int baud_rate);
  ~PosixSerial() override;
  PosixSerial(const PosixSerial&) = delete;
  PosixSerial& operator=(const PosixSerial&) = delete;

  void write(std::span<const std::uint8_t> bytes, Clock::time_point until) override;
  std::size_t read_some(std::span<std::uint8_t> out, Clock::time_point until) override;
  void discard_input() override;
  void interrupt() noexcept override;
  void clear_interrupt() noexcept override;
  std::string path() const override { return path_; }
  int baud_rate() const override { return baud_; }

 private:
  const std::string path_;
  const int baud_;
  int fd_ = -1;
  int wake_ = -1;  // eventfd: readable while an interrupt is raised
};

}  // namespace rcand::plugins::dynamixel
