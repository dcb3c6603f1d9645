// A Logger that keeps every line, so tests can assert on what a plugin logged (and on what it did not).
#pragma once

#include <mutex>
#include <string>
#include <string_view>
#include <vector>

#include "rcand/sdk/logger.hpp"

namespace rcand::sdk::testing {

inline std::string_view level_name(LogLevel level) noexcept {
  switch (level) {
    case LogLevel::Trace: return "trace";
    case LogLevel::Debug: return "debug";
    case LogLevel::Info: return "info";
    case LogLevel::Warn: return "warn";
    case LogLevel::Error: return "error";
  }
  return "info";
}

// Shared sink: every logger of one fake host appends here, in call order.
class LogSink {
 public:
  void append(std::string line) {
    std::lock_guard lock(mutex_);
    lines_.push_back(std::move(line));
  }
  // Not synchronised with concurrent writers: read it from the test thread once plugin work is done.
  const std::vector<std::string>& lines() const noexcept { return lines_; }
  void clear() {
    std::lock_guard lock(mutex_);
    lines_.clear();
  }

 private:
  std::mutex mutex_;
  std::vector<std::string> lines_;
};

// Lines look like "[warn] plugin.org.rcand.teleop: message", the kernel's logger name included.
class RecordingLogger final : public Logger {
 public:
  RecordingLogger(LogSink& sink, std::string name) : sink_(sink), name_(std::move(name)) {}
  void log(LogLevel level, std::string_view message) noexcept override {
    try {
      std::string line = "[";
      line.append(level_name(level)).append("] ").append(name_).append(": ").append(message);
      sink_.append(std::move(line));
    } catch (...) {  // logging never throws into the caller
    }
  }

 private:
  LogSink& sink_;
  std::string name_;
};

}  // namespace rcand::sdk::testing
