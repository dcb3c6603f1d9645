// The service manager's end of sd_notify for tests: a datagram socket in a private directory, and an environment
// variable set for a scope (tests that use it start no threads that read the environment meanwhile).
#pragma once

#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <optional>
#include <stdexcept>
#include <string>

#include "temp_dir.hpp"

namespace rcand::test {

class ScopedEnv {
 public:
  ScopedEnv(const char* name, const std::string& value) : name_(name) {
    if (const char* old = std::getenv(name)) old_ = old;
    ::setenv(name, value.c_str(), 1);
  }
  ~ScopedEnv() {
    if (old_) ::setenv(name_, old_->c_str(), 1);
    else ::unsetenv(name_);
  }
  ScopedEnv(const ScopedEnv&) = delete;
  ScopedEnv& operator=(const ScopedEnv&) = delete;

 private:
  const char* name_;
  std::optional<std::string> old_;
};

class NotifySocket {
 public:
  NotifySocket() : fd_(::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0)), path_((dir_.path() / "notify").string()) {
    sockaddr_un address{};
    address.sun_family = AF_UNIX;
    std::strncpy(address.sun_path, path_.c_str(), sizeof address.sun_path - 1);
    if (fd_ < 0 || ::bind(fd_, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0)
      throw std::runtime_error("cannot bind a notify socket at " + path_);
  }
  ~NotifySocket() { ::close(fd_); }
  NotifySocket(const NotifySocket&) = delete;
  NotifySocket& operator=(const NotifySocket&) = delete;

  const std::string& path() const noexcept { return path_; }
  // The next datagram, or "" when none came within `timeout_ms`.
  std::string next(int timeout_ms = 5000) const {
    pollfd in{fd_, POLLIN, 0};
    if (::poll(&in, 1, timeout_ms) != 1) return {};
    char buffer[512];
    const ssize_t got = ::recv(fd_, buffer, sizeof buffer, 0);
    return got > 0 ? std::string(buffer, static_cast<std::size_t>(got)) : std::string();
  }
  // The next datagram other than "WATCHDOG=1" (the keep-alives interleave with state changes).
  std::string next_state(int timeout_ms = 5000) const {
    for (;;) {
      std::string message = next(timeout_ms);
      if (message != "WATCHDOG=1") return message;
    }
  }

 private:
  TempDir dir_;
  int fd_;
  std::string path_;
};

}  // namespace rcand::test
