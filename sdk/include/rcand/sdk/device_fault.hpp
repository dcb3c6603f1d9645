// A driver that cannot use its hardware says so with a DeviceFault, thrown from its factory, start() or a command:
// what it tried (the message), the device (a path, a bus and address), the operating system's error, and what the
// operator can do about it (the hint). The kernel keeps the parts apart: GET /api/status and GET /api/plugins show
// `reason` (the message), `device`, `os_error` and `hint` for the failed instance, and so do rcanctl and the dashboard.
//
//   throw sdk::DeviceFault("cannot open /dev/ttyUSB0: No such file or directory", "/dev/ttyUSB0",
//                          "No such file or directory", "is the U2D2 plugged in? ls /dev/serial/by-id/");
//
// Header-only and kernel-version-neutral: a kernel that does not know the type still records what() (the message
// followed by the hint in parentheses), so plugins may throw it whatever kernel they run on.
#pragma once

#include <stdexcept>
#include <string>

#include "rcand/sdk/export.hpp"

namespace rcand::sdk {

class RCAND_INTERFACE DeviceFault : public std::runtime_error {
 public:
  explicit DeviceFault(const std::string& message, std::string device = {}, std::string os_error = {}, std::string hint = {})
      : std::runtime_error(hint.empty() ? message : message + " (" + hint + ")"),
        message_(message),
        device_(std::move(device)),
        os_error_(std::move(os_error)),
        hint_(std::move(hint)) {}

  const std::string& message() const noexcept { return message_; }    // what failed, for people
  const std::string& device() const noexcept { return device_; }      // "/dev/ttyUSB0", "/dev/i2c-1 0x40"; may be empty
  const std::string& os_error() const noexcept { return os_error_; }  // strerror() of the call that failed; may be empty
  const std::string& hint() const noexcept { return hint_; }          // what to try; may be empty

 private:
  std::string message_, device_, os_error_, hint_;
};

}  // namespace rcand::sdk
