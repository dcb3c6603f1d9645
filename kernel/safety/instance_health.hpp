// Whether one plugin instance (a capability or a driver) is still in service. An exception from plugin code
// marks it failed once, with the first reason; it stays failed until rcand restarts (or its plugin is reloaded).
#pragma once

#include <atomic>
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

 private:
  std::atomic<bool> failed_{false};
  mutable std::mutex mutex_;  // guards reason_ only
  std::string reason_;
};

}  // namespace rcand::kernel
