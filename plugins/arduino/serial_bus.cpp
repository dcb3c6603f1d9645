#include "serial_bus.hpp"

#include <fcntl.h>
#include <poll.h>
#include <sys/eventfd.h>
#include <termios.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstring>
#include <utility>

namespace rcand::plugins::arduino {

namespace {

std::string arduino_errno_text(int error) { return std::strerror(error); }

timespec arduino_time_left(ArduinoBus::Clock::time_point until) {
  const auto left = std::chrono::duration_cast<std::chrono::nanoseconds>(until - ArduinoBus::Clock::now()).count();
  const long long ns = std::clamp<long long>(left, 0, 60'000'000'000LL);
  return timespec{static_cast<time_t>(ns / 1'000'000'000), static_cast<long>(ns % 1'000'000'000)};
}

std::optional<speed_t> arduino_speed_of(int baud) {
  constexpr std::array<std::pair<int, speed_t>, 8> kSpeeds{{{9600, B9600},
                                                            {19200, B19200},
                                                            {38400, B38400},
                                                            {57600, B57600},
                                                            {115200, B115200},
                                                            {230400, B230400},
                                                            {460800, B460800},
                                                            {500000, B500000}}};
  for (const auto& [rate, speed] : kSpeeds)
    if (rate == baud) return speed;
  return std::nullopt;
}

}  // namespace

ArduinoBus::ArduinoBus(std::string path, int baud) : path_(std::move(path)), baud_(baud) {
  const auto speed = arduino_speed_of(baud_);
  if (!speed) throw SerialFault("cannot set " + path_ + " to " + std::to_string(baud_) + " baud: not a standard rate", path_);
  fd_ = ::open(path_.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
  if (fd_ < 0) {
    const int error = errno;
    const std::string hint = error == EACCES   ? "add the rcand user to the dialout group"
                             : error == ENOENT ? "is the Arduino plugged in? ls /dev/serial/by-id/ lists the USB serial boards"
                                               : "";
    throw SerialFault("cannot open " + path_ + ": " + arduino_errno_text(error), path_, arduino_errno_text(error), hint);
  }
  termios tio{};
  if (::tcgetattr(fd_, &tio) != 0) {
    const int error = errno;
    ::close(fd_);
    throw SerialFault(path_ + " is not a serial port: " + arduino_errno_text(error), path_, arduino_errno_text(error),
                      "set the driver's port to the Arduino's tty (ls /dev/serial/by-id/)");
  }
  ::cfmakeraw(&tio);  // 8N1, no echo, no line editing, no CR/LF translation, no XON/XOFF
  tio.c_cflag &= ~static_cast<tcflag_t>(CRTSCTS | CSTOPB | PARENB);
  tio.c_cflag |= CLOCAL | CREAD;
  tio.c_cc[VMIN] = 0;
  tio.c_cc[VTIME] = 0;
  ::cfsetispeed(&tio, *speed);
  ::cfsetospeed(&tio, *speed);
  if (::tcsetattr(fd_, TCSANOW, &tio) != 0) {
    const int error = errno;
    ::close(fd_);
    throw SerialFault("cannot configure " + path_ + " at " + std::to_string(baud_) + " baud: " + arduino_errno_text(error), path_,
                      arduino_errno_text(error));
  }
  wake_ = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
  if (wake_ < 0) {
    const int error = errno;
    ::close(fd_);
    throw SerialFault("eventfd: " + arduino_errno_text(error));
  }
  discard_input();
}

ArduinoBus::~ArduinoBus() {
  if (wake_ >= 0) ::close(wake_);
  if (fd_ >= 0) ::close(fd_);
}

void ArduinoBus::send(std::string_view line, Clock::time_point until) {
  out_of_step_ = true;  // its reply (if any) is not read here
  while (!line.empty()) {
    const ssize_t n = ::write(fd_, line.data(), line.size());
    if (n > 0) {
      line.remove_prefix(static_cast<std::size_t>(n));
      continue;
    }
    if (n < 0 && errno == EINTR) continue;
    if (n < 0 && errno != EAGAIN) throw SerialFault("write to " + path_ + ": " + arduino_errno_text(errno), path_);
    pollfd pfd{fd_, POLLOUT, 0};  // the output buffer is full: wait for room, never past `until`
    const timespec wait = arduino_time_left(until);
    if ((wait.tv_sec == 0 && wait.tv_nsec == 0) || ::ppoll(&pfd, 1, &wait, nullptr) == 0)
      throw SerialFault("write to " + path_ + ": the port accepts no data (unplugged or hung)", path_);
  }
}

std::optional<std::string> ArduinoBus::read_line(Clock::time_point until) {
  for (;;) {
    if (auto line = splitter_.next()) return line;
    pollfd fds[2] = {{wake_, POLLIN, 0}, {fd_, POLLIN, 0}};
    const timespec wait = arduino_time_left(until);
    const int ready = ::ppoll(fds, 2, &wait, nullptr);
    if (ready < 0) {
      if (errno == EINTR) continue;
      throw SerialFault("poll on " + path_ + ": " + arduino_errno_text(errno), path_);
    }
    if (fds[0].revents & POLLIN) throw Interrupted();
    if (ready == 0) return std::nullopt;
    if (fds[1].revents & (POLLERR | POLLNVAL)) throw SerialFault(path_ + ": the device went away (unplugged?)", path_);
    char buffer[256];
    const ssize_t n = ::read(fd_, buffer, sizeof buffer);
    if (n > 0) {
      splitter_.feed(std::string_view(buffer, static_cast<std::size_t>(n)));
      continue;
    }
    if (n < 0 && (errno == EAGAIN || errno == EINTR)) continue;
    if (n == 0 || errno == EIO) throw SerialFault(path_ + ": the device went away (unplugged?)", path_);
    throw SerialFault("read from " + path_ + ": " + arduino_errno_text(errno), path_);
  }
}

std::optional<Reply> ArduinoBus::transact(std::string_view line, Expect expect, Clock::time_point until) {
  if (out_of_step_) discard_input();
  send(line, until);  // out of step until the reply is in: an interrupt or a timeout leaves it on its way
  for (;;) {
    const auto text = read_line(until);
    if (!text) return std::nullopt;
    Reply reply = parse_reply(*text);
    const bool wanted = reply.kind == Reply::Kind::Error ||
                        (expect == Expect::Ack ? reply.kind == Reply::Kind::Ack : reply.kind == Reply::Kind::Sensor);
    if (!wanted) {
      ++skipped_;
      continue;
    }
    out_of_step_ = false;
    return reply;
  }
}

void ArduinoBus::discard_input() {
  ::tcflush(fd_, TCIFLUSH);
  splitter_.clear();
  out_of_step_ = false;
}

void ArduinoBus::interrupt() noexcept {
  const std::uint64_t one = 1;
  (void)!::write(wake_, &one, sizeof one);
}

void ArduinoBus::clear_interrupt() noexcept {
  std::uint64_t value = 0;
  (void)!::read(wake_, &value, sizeof value);
}

}  // namespace rcand::plugins::arduino
