// The plugin's logger: the kernel routes it to spdlog as "plugin.<id>". Never pass secrets.
#pragma once

#include <sstream>
#include <string_view>
#include <utility>

#include "rcand/sdk/export.hpp"

namespace rcand::sdk {

enum class LogLevel { Trace, Debug, Info, Warn, Error };

class RCAND_INTERFACE Logger {
 public:
  virtual ~Logger() = default;
  // Any thread; does not block on I/O (the kernel's sink is asynchronous-safe and line buffered).
  virtual void log(LogLevel level, std::string_view message) noexcept = 0;

  template <class... Args> void debug(Args&&... args) noexcept { write(LogLevel::Debug, std::forward<Args>(args)...); }
  template <class... Args> void info(Args&&... args) noexcept { write(LogLevel::Info, std::forward<Args>(args)...); }
  template <class... Args> void warn(Args&&... args) noexcept { write(LogLevel::Warn, std::forward<Args>(args)...); }
  template <class... Args> void error(Args&&... args) noexcept { write(LogLevel::Error, std::forward<Args>(args)...); }

 private:
  template <class... Args> void write(LogLevel level, Args&&... args) noexcept {
    try {
      std::ostringstream out;
      (out << ... << std::forward<Args>(args));
      log(level, out.str());
    } catch (...) {  // logging never throws into the caller
    }
  }
};

}  // namespace rcand::sdk
