// spdlog setup: "kernel.*" loggers for the kernel, "plugin.<id>" for plugins; one stderr sink, journald-friendly.
#pragma once

#include <spdlog/formatter.h>
#include <spdlog/logger.h>

#include <chrono>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <unordered_map>

#include "rcand/sdk/logger.hpp"

namespace rcand {

// Sets the level ("trace".."error") and the formatter (make_log_formatter) of every logger, made before or after.
// Call early in main, before anything is logged.
void configure_logging(std::string_view level);

// The formatter configure_logging installs: "<N>level [name] message" for journald, "time level [name] message"
// elsewhere; the message always through the one rule for log text (libs/base/log_text.hpp: escaped, bounded).
std::unique_ptr<spdlog::formatter> make_log_formatter(bool journal);

// The named logger, created on first use with the shared sink.
std::shared_ptr<spdlog::logger> logger(const std::string& name);

// Caps the log lines a source (a principal, a plugin, a client address) can cause: at most `lines_per_second` per
// source in each one-second window; the first line a source gets after some were held back carries how many
// (log "suppressed K lines" then). At most `max_sources` are tracked; beyond that, new sources share one budget.
// Any thread; one short lock, never held around logging.
class LogRateLimiter {
 public:
  struct Verdict {
    bool log = false;
    std::uint64_t suppressed = 0;  // lines of this source left out since its last logged line
  };
  explicit LogRateLimiter(std::uint32_t lines_per_second, std::size_t max_sources = 1024)
      : per_second_(lines_per_second), max_sources_(max_sources) {}
  Verdict admit(std::string_view source, std::chrono::steady_clock::time_point now = std::chrono::steady_clock::now());

 private:
  struct Window {
    std::chrono::steady_clock::time_point start{};
    std::uint32_t count = 0;
    std::uint64_t suppressed = 0;
  };
  const std::uint32_t per_second_;
  const std::size_t max_sources_;
  std::mutex mutex_;
  std::unordered_map<std::string, Window> windows_;
};

// The SDK Logger a plugin instance gets: forwards to logger("plugin.<id>"), at most kLinesPerSecond lines a second.
class PluginLogger final : public sdk::Logger {
 public:
  static constexpr std::uint32_t kLinesPerSecond = 200;
  explicit PluginLogger(const std::string& plugin_id);
  void log(sdk::LogLevel level, std::string_view message) noexcept override;

 private:
  std::shared_ptr<spdlog::logger> logger_;
  LogRateLimiter limit_{kLinesPerSecond, 1};
};

}  // namespace rcand
