#include "libs/http/http_logger.hpp"

#include <spdlog/spdlog.h>

namespace rcand::http::detail {

std::shared_ptr<spdlog::logger> http_logger() {
  if (auto registered = spdlog::get("kernel.http")) return registered;
  auto fallback = spdlog::default_logger();
  auto made = std::make_shared<spdlog::logger>("kernel.http", fallback->sinks().begin(), fallback->sinks().end());
  made->set_level(fallback->level());
  return made;
}

}  // namespace rcand::http::detail
