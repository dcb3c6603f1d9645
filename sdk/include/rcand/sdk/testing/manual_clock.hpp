// A clock that moves only when the test says so, so timers and timelines are deterministic.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>

#include "rcand/sdk/clock.hpp"

namespace rcand::sdk::testing {

class ManualClock final : public Clock {
 public:
  // Wall time starts at a fixed, recognisable instant (2023-11-14T22:13:20Z) so outputs do not vary per run.
  static constexpr std::int64_t kWallEpochMs = 1'700'000'000'000;

  std::int64_t now_us() const noexcept override { return now_us_.load(); }
  std::int64_t wall_ms() const noexcept override { return kWallEpochMs + now_us_.load() / 1000; }

  // Moves time forward; a target in the past is ignored (the clock is monotonic).
  void set_us(std::int64_t us) noexcept {
    std::int64_t current = now_us_.load();
    while (us > current && !now_us_.compare_exchange_weak(current, us)) {
    }
  }
  void advance(std::chrono::microseconds by) noexcept { set_us(now_us() + by.count()); }

 private:
  std::atomic<std::int64_t> now_us_{0};
};

}  // namespace rcand::sdk::testing
