#include "kernel/plugins/guarded.hpp"

#include <spdlog/sinks/null_sink.h>

#include "libs/base/bounded_text.hpp"

#include <mutex>

namespace rcand::kernel {

std::shared_ptr<spdlog::logger> plugins_logger() noexcept {
  static constexpr const char* kName = "kernel.plugins";
  static std::mutex mutex;
  try {
    std::lock_guard lock(mutex);
    if (auto existing = spdlog::get(kName)) return existing;
    // Nobody configured it (unit tests, tools): share the default logger's sinks and level.
    auto logger = spdlog::default_logger()->clone(kName);
    spdlog::register_logger(logger);
    return logger;
  } catch (...) {
    // Registration raced with someone else's, or allocation failed: use theirs, or log nowhere.
    try {
      if (auto existing = spdlog::get(kName)) return existing;
    } catch (...) {
    }
  }
  static const auto fallback = std::make_shared<spdlog::logger>(kName, std::make_shared<spdlog::sinks::null_sink_mt>());
  return fallback;
}

namespace detail {
namespace {
constexpr std::size_t kFailureTextLimit = 1000;
}  // namespace

void record_plugin_throw(std::string_view who, std::string_view what, Fault& failure, std::string_view message,
                         const std::exception* exception) noexcept {
  try {
    failure = exception != nullptr ? fault_of(*exception) : Fault{std::string(message), {}, {}, {}};
    failure.reason = bounded_text(failure.reason, kFailureTextLimit);  // a plugin may quote a client's megabyte
  } catch (...) {
    failure = {};  // cannot allocate the copy: leave a recognisable empty failure
  }
  try {
    plugins_logger()->error("{}: {} threw: {}", who, what, failure.reason);
  } catch (...) {  // logging never throws into the caller
  }
}

}  // namespace detail
}  // namespace rcand::kernel
