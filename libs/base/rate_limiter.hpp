// Request rate limits (docs/protocol.md §6.4): a token bucket per key (a principal, or a client address), refilled at `per_s`
// and holding at most `per_s * burst_s` requests. The e-stop paths never reach it: the Api exempts them before asking.
// The table is bounded: full (idle) buckets are dropped first, so an attacker cycling through keys cannot grow it.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <unordered_map>

namespace rcand {

struct RateLimit {
  double per_s = 0;      // 0 = unlimited
  double burst_s = 2.0;  // the bucket holds this many seconds' worth of requests
};

class RateLimiter {
 public:
  explicit RateLimiter(RateLimit limit, std::size_t max_keys = 4096);

  // nullopt: admitted (one request taken from `key`'s bucket). Otherwise refused, with the time until the bucket
  // holds a request again (for Retry-After). Any thread.
  std::optional<std::chrono::milliseconds> admit(std::string_view key, std::int64_t now_us);
  const RateLimit& limit() const noexcept { return limit_; }
  std::size_t keys() const;

 private:
  struct Bucket {
    double tokens = 0;
    std::int64_t updated_us = 0;
  };
  const RateLimit limit_;
  const double capacity_;
  const std::size_t max_keys_;
  mutable std::mutex mutex_;  // held for a lookup and a few arithmetic operations only
  std::unordered_map<std::string, Bucket> buckets_;

  void make_room(std::int64_t now_us);
};

}  // namespace rcand
