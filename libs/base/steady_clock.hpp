// The kernel's sdk::Clock: std::chrono::steady_clock for durations, system_clock for timestamps.
#pragma once

#include <chrono>

#include "rcand/sdk/clock.hpp"

namespace rcand {

class SteadyClock final : public sdk::Clock {
 public:
  std::int64_t now_us() const noexcept override {
    using namespace std::chrono;
    return duration_cast<microseconds>(steady_clock::now().time_since_epoch()).count();
  }
  std::int64_t wall_ms() const noexcept override {
    using namespace std::chrono;
    return duration_cast<milliseconds>(system_clock::now().time_since_epoch()).count();
  }
};

}  // namespace rcand
