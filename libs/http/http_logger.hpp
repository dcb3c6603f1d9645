// The "kernel.http" spdlog logger, so this module logs without depending on the core's logging setup.
#pragma once

#include <spdlog/logger.h>

#include <memory>

namespace rcand::http::detail {

// The registered "kernel.http" logger when the kernel configured one, else an unregistered logger with that name
// writing to the default logger's sinks (so a later registration by the kernel still succeeds).
std::shared_ptr<spdlog::logger> http_logger();

}  // namespace rcand::http::detail
