#include "libs/base/logging.hpp"

#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <mutex>

namespace rcand {
namespace {
std::mutex g_create_mutex;  // only serializes logger creation, never logging itself
}

void configure_logging(std::string_view level) {
  // Every log goes to stderr (journald captures it); stdout carries only the ready line.
  if (!spdlog::get("rcand")) spdlog::set_default_logger(spdlog::stderr_color_mt("rcand"));
  spdlog::set_level(spdlog::level::from_str(std::string(level)));
  // No timestamps when journald adds its own would be nicer; keep them for plain terminals and test logs.
  spdlog::set_pattern("%Y-%m-%dT%H:%M:%S.%e %^%l%$ [%n] %v");
}

std::shared_ptr<spdlog::logger> logger(const std::string& name) {
  if (auto existing = spdlog::get(name)) return existing;
  std::lock_guard lock(g_create_mutex);
  if (auto existing = spdlog::get(name)) return existing;
  auto created = spdlog::stderr_color_mt(name);
  return created;
}

LogRateLimiter::Verdict LogRateLimiter::admit(std::string_view source, std::chrono::steady_clock::time_point now) {
  std::lock_guard lock(mutex_);
  auto it = windows_.find(std::string(source));
  if (it == windows_.end()) {
    if (windows_.size() >= max_sources_) {
      std::erase_if(windows_, [now](const auto& item) {
        return now - item.second.start >= std::chrono::seconds(1) && item.second.suppressed == 0;
      });
    }
    // Still full: every source not yet tracked shares one budget (the table stays bounded).
    it = windows_.size() < max_sources_ ? windows_.try_emplace(std::string(source)).first
                                        : windows_.try_emplace(std::string("*overflow*")).first;
  }
  Window& window = it->second;
  if (now - window.start >= std::chrono::seconds(1)) {
    window.start = now;
    window.count = 0;
  }
  if (window.count >= per_second_) {
    ++window.suppressed;
    return {false, 0};
  }
  ++window.count;
  Verdict verdict{true, window.suppressed};
  window.suppressed = 0;
  return verdict;
}

PluginLogger::PluginLogger(const std::string& plugin_id) : logger_(logger("plugin." + plugin_id)) {}

void PluginLogger::log(sdk::LogLevel level, std::string_view message) noexcept {
  try {
    spdlog::level::level_enum spd = spdlog::level::info;
    switch (level) {
      case sdk::LogLevel::Trace: spd = spdlog::level::trace; break;
      case sdk::LogLevel::Debug: spd = spdlog::level::debug; break;
      case sdk::LogLevel::Info: spd = spdlog::level::info; break;
      case sdk::LogLevel::Warn: spd = spdlog::level::warn; break;
      case sdk::LogLevel::Error: spd = spdlog::level::err; break;
    }
    if (!logger_->should_log(spd)) return;  // lines below the level cost nothing and count for nothing
    const auto verdict = limit_.admit("plugin");
    if (!verdict.log) return;
    if (verdict.suppressed > 0)
      logger_->warn("{} log lines of this plugin suppressed (more than {} a second)", verdict.suppressed, kLinesPerSecond);
    logger_->log(spd, "{}", message);
  } catch (...) {
  }
}

}  // namespace rcand
