// A lock-free latency histogram: one relaxed atomic add per observation, so recording on the request path (and on
// the stop path's answer) takes no lock and never waits for a scrape. Bounds are in seconds, fixed at construction.
#pragma once

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <span>

#include "services/telemetry/metrics_text.hpp"

namespace rcand::services::telemetry {

// HTTP handlers: from a status read (tens of microseconds) to a capability handler's timeout.
inline constexpr std::array<double, 14> kRequestBounds{0.0001, 0.00025, 0.0005, 0.001, 0.0025, 0.005, 0.01,
                                                       0.025,  0.05,    0.1,    0.25,  0.5,    1.0,   10.0};
// A stop: the drivers' halts, bounded by Estop::kHaltDeadline (100 ms).
inline constexpr std::array<double, 12> kHaltBounds{0.00005, 0.0001, 0.00025, 0.0005, 0.001, 0.0025,
                                                    0.005,   0.01,   0.025,   0.05,   0.1,   0.25};

class LatencyHistogram {
 public:
  explicit LatencyHistogram(std::span<const double> bounds) : bounds_(bounds) {}

  void observe(std::chrono::nanoseconds elapsed) noexcept {
    const double seconds = std::chrono::duration<double>(elapsed).count();
    std::size_t i = 0;
    while (i < bounds_.size() && i < kMaxBuckets && seconds > bounds_[i]) ++i;
    buckets_[i].fetch_add(1, std::memory_order_relaxed);  // i == bounds_.size(): only in +Inf
    sum_ns_.fetch_add(static_cast<std::uint64_t>(elapsed.count() < 0 ? 0 : elapsed.count()), std::memory_order_relaxed);
  }

  // A scrape's view. Observations racing it may be in a bucket and not yet in the sum: the format tolerates that.
  HistogramSample read() const {
    HistogramSample sample;
    sample.bounds = bounds_;
    std::uint64_t running = 0;
    for (std::size_t i = 0; i < bounds_.size() && i < kMaxBuckets; ++i) {
      running += buckets_[i].load(std::memory_order_relaxed);
      sample.cumulative.push_back(running);
    }
    sample.count = running + buckets_[std::min(bounds_.size(), kMaxBuckets)].load(std::memory_order_relaxed);
    sample.sum = static_cast<double>(sum_ns_.load(std::memory_order_relaxed)) / 1e9;
    return sample;
  }

 private:
  static constexpr std::size_t kMaxBuckets = 16;
  std::span<const double> bounds_;
  std::array<std::atomic<std::uint64_t>, kMaxBuckets + 1> buckets_{};
  std::atomic<std::uint64_t> sum_ns_{0};
};

}  // namespace rcand::services::telemetry
