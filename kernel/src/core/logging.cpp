#include "rcand/kernel/core/logging.hpp"

#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <mutex>

namespace rcand::kernel {
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

PluginLogger::PluginLogger(const std::string& plugin_id) : logger_(logger("plugin." + plugin_id)) {}

void PluginLogger::log(sdk::LogLevel level, std::string_view message) noexcept {
  try {
    switch (level) {
      case sdk::LogLevel::Trace: logger_->trace("{}", message); break;
      case sdk::LogLevel::Debug: logger_->debug("{}", message); break;
      case sdk::LogLevel::Info: logger_->info("{}", message); break;
      case sdk::LogLevel::Warn: logger_->warn("{}", message); break;
      case sdk::LogLevel::Error: logger_->error("{}", message); break;
    }
  } catch (...) {
  }
}

}  // namespace rcand::kernel
