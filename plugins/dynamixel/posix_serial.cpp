#include "posix_serial.hpp"

#include <asm/termbits.h>  // termios2, BOTHER: any baud rate, not only the Bnnn constants
#include <fcntl.h>
#include <poll.h>
#include <sys/eventfd.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

namespace rcand::plugins::dynamixel {

namespace {

std::string errno_text(int error) { return std::strerror(error); }

// What is left until `until`, for ppoll (microsecond waits: a reply at 1 Mbps takes well under a millisecond).
timespec remaining(SerialLink::Clock::time_point until) {
  const auto left = std::chrono::duration_cast<std::chrono::nanoseconds>(until - SerialLink::Clock::now()).count();
  const long long ns = std::clamp<long long>(left, 0, 60'000'000'000LL);
  return timespec{static_cast<time_t>(ns / 1'000'000'000), static_cast<long>(ns % 1'000'000'000)};
}

}  // namespace

PosixSerial::PosixSerial(std::string path, int baud_rate) : path_(std::move(path)), baud_(baud_rate) {
  fd_ = ::open(path_.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
  if (fd_ < 0) {
    const int error = errno;
    std::string hint = error == EACCES   ? "add the rcand user to the dialout group"
                       : error == ENOENT ? "is the U2D2 plugged in? ls /dev/serial/by-id/ lists the USB serial adapters"
                                         : "";
    throw SerialError("cannot open " + path_ + ": " + errno_text(error), path_, errno_text(error), hint);
  }
  termios2 tio{};
  if (::ioctl(fd_, TCGETS2, &tio) != 0) {
    const int error = errno;
    ::close(fd_);
    throw SerialError(path_ + " is not a serial port: " + errno_text(error), path_, errno_text(error),
                      "set the driver's port to the adapter's tty (ls /dev/serial/by-id/)");
  }
  // Raw: no echo, no line editing, no translation of CR/LF or of 0x11/0x13, 8 data bits, no parity, one stop bit.
  tio.c_iflag &= ~static_cast<tcflag_t>(IGNBRK | BRKINT | PARMRK | ISTRIP | INLCR | IGNCR | ICRNL | IXON | IXOFF | IXANY);
  tio.c_oflag &= ~static_cast<tcflag_t>(OPOST);
  tio.c_lflag &= ~static_cast<tcflag_t>(ECHO | ECHONL | ICANON | ISIG | IEXTEN);
  tio.c_cflag &= ~static_cast<tcflag_t>(CSIZE | PARENB | CSTOPB | CRTSCTS | CBAUD);
  tio.c_cflag |= CS8 | CREAD | CLOCAL | BOTHER;
  tio.c_ispeed = tio.c_ospeed = static_cast<speed_t>(baud_);
  tio.c_cc[VMIN] = 0;
  tio.c_cc[VTIME] = 0;
  if (::ioctl(fd_, TCSETS2, &tio) != 0) {
    const int error = errno;
    ::close(fd_);
    throw SerialError("cannot configure " + path_ + " at " + std::to_string(baud_) + " bps: " + errno_text(error));
  }
  wake_ = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
  if (wake_ < 0) {
    const int error = errno;
    ::close(fd_);
    throw SerialError("eventfd: " + errno_text(error));
  }
  discard_input();
}

PosixSerial::~PosixSerial() {
  if (wake_ >= 0) ::close(wake_);
  if (fd_ >= 0) ::close(fd_);
}

void PosixSerial::write(std::span<const std::uint8_t> bytes, Clock::time_point until) {
  while (!bytes.empty()) {
    const ssize_t n = ::write(fd_, bytes.data(), bytes.size());
    if (n > 0) {
      bytes = bytes.subspan(static_cast<std::size_t>(n));
      continue;
    }
    if (n < 0 && errno == EINTR) continue;
    if (n < 0 && errno != EAGAIN) throw SerialError("write to " + path_ + ": " + errno_text(errno));
    // The output buffer is full: wait for room, up to `until` (a stalled adapter must not hold the thread forever).
    pollfd pfd{fd_, POLLOUT, 0};
    const timespec wait = remaining(until);
    if ((wait.tv_sec == 0 && wait.tv_nsec == 0) || ::ppoll(&pfd, 1, &wait, nullptr) == 0)
      throw SerialError("write to " + path_ + ": the adapter accepts no data (unplugged or stalled)");
  }
}

std::size_t PosixSerial::read_some(std::span<std::uint8_t> out, Clock::time_point until) {
  for (;;) {
    pollfd fds[2] = {{wake_, POLLIN, 0}, {fd_, POLLIN, 0}};
    const timespec wait = remaining(until);
    const int ready = ::ppoll(fds, 2, &wait, nullptr);
    if (ready < 0) {
      if (errno == EINTR) continue;
      throw SerialError("poll on " + path_ + ": " + errno_text(errno));
    }
    if (fds[0].revents & POLLIN) throw Interrupted();
    if (ready == 0) return 0;
    if (fds[1].revents & (POLLERR | POLLHUP | POLLNVAL)) throw SerialError(path_ + ": the device went away (unplugged?)");
    const ssize_t n = ::read(fd_, out.data(), out.size());
    if (n > 0) return static_cast<std::size_t>(n);
    if (n < 0 && (errno == EAGAIN || errno == EINTR)) continue;
    throw SerialError("read from " + path_ + ": " + (n == 0 ? std::string("end of file") : errno_text(errno)));
  }
}

void PosixSerial::discard_input() { ::ioctl(fd_, TCFLSH, TCIFLUSH); }

void PosixSerial::interrupt() noexcept {
  const std::uint64_t one = 1;
  (void)!::write(wake_, &one, sizeof one);
}

void PosixSerial::clear_interrupt() noexcept {
  std::uint64_t value = 0;
  (void)!::read(wake_, &value, sizeof value);
}

}  // namespace rcand::plugins::dynamixel
