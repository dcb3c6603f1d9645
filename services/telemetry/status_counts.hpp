// Answers per HTTP status code for one route, lock-free: a route answers a handful of distinct codes, so a few
// slots claimed on first use (a compare-and-swap) replace a counter per possible code (500 of them were 4 KB per
// route, 0.3 MB of the idle robot's heap for ~70 routes). Codes past the last slot are counted as "other".
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <functional>

namespace rcand::services::telemetry {

class StatusCounts {
 public:
  // More distinct codes than any route answers (success, a few 4xx, 500, 503).
  static constexpr std::size_t kSlots = 12;

  // Any thread; an out-of-range status counts as 500 (what the client saw from a handler that set none).
  void add(int status) noexcept {
    const auto code = static_cast<std::uint16_t>(status >= 100 && status < 600 ? status : 500);
    for (auto& slot : slots_) {
      std::uint16_t held = slot.code.load(std::memory_order_acquire);
      if (held == 0 && slot.code.compare_exchange_strong(held, code, std::memory_order_acq_rel)) held = code;
      if (held == code) {
        slot.count.fetch_add(1, std::memory_order_relaxed);
        return;
      }
    }
    other_.fetch_add(1, std::memory_order_relaxed);
  }

  // Each code seen (in the order first seen) with its count; `other` last when any fell past the slots (code 0).
  void for_each(const std::function<void(int code, std::uint64_t count)>& visit) const {
    for (const auto& slot : slots_) {
      const std::uint16_t code = slot.code.load(std::memory_order_acquire);
      if (code == 0) break;  // slots are claimed in order
      if (const auto n = slot.count.load(std::memory_order_relaxed); n > 0) visit(code, n);
    }
    if (const auto n = other_.load(std::memory_order_relaxed); n > 0) visit(0, n);
  }

 private:
  struct Slot {
    std::atomic<std::uint16_t> code{0};  // 0: free
    std::atomic<std::uint64_t> count{0};
  };
  std::array<Slot, kSlots> slots_{};
  std::atomic<std::uint64_t> other_{0};
};

}  // namespace rcand::services::telemetry
