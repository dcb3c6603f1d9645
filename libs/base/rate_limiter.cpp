#include "libs/base/rate_limiter.hpp"

#include <algorithm>
#include <cmath>

namespace rcand {

RateLimiter::RateLimiter(RateLimit limit, std::size_t max_keys)
    : limit_(limit), capacity_(std::max(1.0, limit.per_s * limit.burst_s)), max_keys_(std::max<std::size_t>(max_keys, 1)) {}

std::optional<std::chrono::milliseconds> RateLimiter::admit(std::string_view key, std::int64_t now_us) {
  if (limit_.per_s <= 0) return std::nullopt;
  std::lock_guard lock(mutex_);
  auto found = buckets_.find(std::string(key));
  if (found == buckets_.end()) {
    if (buckets_.size() >= max_keys_) make_room(now_us);
    found = buckets_.emplace(std::string(key), Bucket{capacity_, now_us}).first;
  }
  Bucket& bucket = found->second;
  const double elapsed_s = static_cast<double>(std::max<std::int64_t>(0, now_us - bucket.updated_us)) / 1e6;
  bucket.tokens = std::min(capacity_, bucket.tokens + elapsed_s * limit_.per_s);
  bucket.updated_us = std::max(bucket.updated_us, now_us);
  if (bucket.tokens >= 1.0) {
    bucket.tokens -= 1.0;
    return std::nullopt;
  }
  const double wait_ms = std::ceil((1.0 - bucket.tokens) / limit_.per_s * 1000.0);
  return std::chrono::milliseconds(static_cast<std::int64_t>(std::max(1.0, wait_ms)));
}

std::size_t RateLimiter::keys() const {
  std::lock_guard lock(mutex_);
  return buckets_.size();
}

// A bucket that would be full by now belongs to a key that has been quiet: forgetting it changes nothing. When every
// key is busy, the one idle longest goes (its owner starts again from a full bucket: generous, never a lock-out).
void RateLimiter::make_room(std::int64_t now_us) {
  const double refill_us = capacity_ / limit_.per_s * 1e6;
  std::erase_if(buckets_, [&](const auto& entry) { return static_cast<double>(now_us - entry.second.updated_us) >= refill_us; });
  if (buckets_.size() < max_keys_) return;
  const auto oldest = std::min_element(buckets_.begin(), buckets_.end(),
                                       [](const auto& a, const auto& b) { return a.second.updated_us < b.second.updated_us; });
  buckets_.erase(oldest);
}

}  // namespace rcand
