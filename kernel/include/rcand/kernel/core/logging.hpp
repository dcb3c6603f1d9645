// spdlog setup: "kernel.*" loggers for the kernel, "plugin.<id>" for plugins; one stderr sink, journald-friendly.
#pragma once

#include <spdlog/logger.h>

#include <memory>
#include <string>
#include <string_view>

#include "rcand/sdk/logger.hpp"

namespace rcand::kernel {

// Sets the level ("trace".."error") and pattern for every logger made afterwards. Call once, early in main.
void configure_logging(std::string_view level);

// The named logger, created on first use with the shared sink.
std::shared_ptr<spdlog::logger> logger(const std::string& name);

// The SDK Logger a plugin instance gets: forwards to logger("plugin.<id>").
class PluginLogger final : public sdk::Logger {
 public:
  explicit PluginLogger(const std::string& plugin_id);
  void log(sdk::LogLevel level, std::string_view message) noexcept override;

 private:
  std::shared_ptr<spdlog::logger> logger_;
};

}  // namespace rcand::kernel
