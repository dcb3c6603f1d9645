// Time as the kernel sees it; the fake host replaces it with a manual clock.
#pragma once

#include <chrono>
#include <cstdint>

#include "rcand/sdk/export.hpp"

namespace rcand::sdk {

class RCAND_INTERFACE Clock {
 public:
  virtual ~Clock() = default;
  // Any thread, never blocks. Monotonic microseconds since an arbitrary epoch (for durations, timelines).
  virtual std::int64_t now_us() const noexcept = 0;
  // Any thread, never blocks. Unix time in milliseconds (for timestamps people read).
  virtual std::int64_t wall_ms() const noexcept = 0;
};

}  // namespace rcand::sdk
