#include "libs/base/logging.hpp"

#include <spdlog/pattern_formatter.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <mutex>

#include "libs/base/log_text.hpp"
#include "libs/base/systemd_notify.hpp"

namespace rcand {
namespace {
std::mutex g_create_mutex;  // only serializes logger creation, never logging itself

// %* : the line's syslog priority as journald reads it from a stream ("<3>" error ... "<7>" debug/trace).
class JournalPriority final : public spdlog::custom_flag_formatter {
 public:
  void format(const spdlog::details::log_msg& msg, const std::tm&, spdlog::memory_buf_t& dest) override {
    const char* prefix = "<6>";
    switch (msg.level) {
      case spdlog::level::critical: prefix = "<2>"; break;
      case spdlog::level::err: prefix = "<3>"; break;
      case spdlog::level::warn: prefix = "<4>"; break;
      case spdlog::level::info: prefix = "<6>"; break;
      default: prefix = "<7>"; break;
    }
    dest.append(prefix, prefix + 3);
  }
  std::unique_ptr<custom_flag_formatter> clone() const override { return std::make_unique<JournalPriority>(); }
};

// %v : the message, through the one rule for log text (libs/base/log_text.hpp). It replaces spdlog's own %v, so
// every pattern built here escapes and bounds every message, whoever logged it.
class EscapedMessage final : public spdlog::custom_flag_formatter {
 public:
  void format(const spdlog::details::log_msg& msg, const std::tm&, spdlog::memory_buf_t& dest) override {
    append_log_text(std::string_view(msg.payload.data(), msg.payload.size()), dest);
  }
  std::unique_ptr<custom_flag_formatter> clone() const override { return std::make_unique<EscapedMessage>(); }
};

}  // namespace

std::unique_ptr<spdlog::formatter> make_log_formatter(bool journal) {
  auto formatter = std::make_unique<spdlog::pattern_formatter>();
  formatter->add_flag<EscapedMessage>('v');
  // Under systemd, journald keeps each line's priority ("<N>" prefix, read at the start of a line only: a line
  // always starts with rcand's own prefix, and a message can hold no line break) and adds its own timestamp;
  // elsewhere (a terminal, the tests' logs) lines carry the time and a coloured level.
  if (journal) formatter->add_flag<JournalPriority>('*').set_pattern("%*%l [%n] %v");
  else formatter->set_pattern("%Y-%m-%dT%H:%M:%S.%e %^%l%$ [%n] %v");
  return formatter;
}

void configure_logging(std::string_view level) {
  // Every log goes to stderr (journald captures it); stdout carries only the ready line.
  if (!spdlog::get("rcand")) spdlog::set_default_logger(spdlog::stderr_color_mt("rcand"));
  spdlog::set_level(spdlog::level::from_str(std::string(level)));
  spdlog::set_formatter(make_log_formatter(stderr_is_journal()));
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
