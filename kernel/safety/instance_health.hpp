// Whether one plugin instance (a capability or a driver) is still in service. An exception from a lifecycle hook or a
// driver, or a handler that hangs, marks it failed once, with the first reason; it stays failed until rcand restarts
// (or its plugin is reloaded). An exception from a request handler only fails that request (docs/protocol.md §7.16):
// it is counted here and shown as the capability's handler_errors.
#pragma once

#include <atomic>
#include <cstdint>
#include <mutex>
#include <string>

namespace rcand::kernel {

class InstanceHealth {
 public:
  bool failed() const noexcept { return failed_.load(); }
  void mark_failed(std::string why) {
    {
      std::lock_guard lock(mutex_);
      if (reason_.empty()) reason_ = std::move(why);
    }
    failed_.store(true);
  }
  // In service again: only for a plugin reload, once nothing of the failed instance runs any more.
  void reset() {
    std::lock_guard lock(mutex_);
    reason_.clear();
    failed_.store(false);
  }
  std::string reason() const {
    std::lock_guard lock(mutex_);
    return reason_;
  }
  // A request handler threw: that request got 500 INTERNAL; the instance stays in service.
  void count_handler_error() noexcept { handler_errors_.fetch_add(1, std::memory_order_relaxed); }
  std::uint64_t handler_errors() const noexcept { return handler_errors_.load(std::memory_order_relaxed); }

 private:
  std::atomic<bool> failed_{false};
  std::atomic<std::uint64_t> handler_errors_{0};
  mutable std::mutex mutex_;  // guards reason_ only
  std::string reason_;
};

}  // namespace rcand::kernel
