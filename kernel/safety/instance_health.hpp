// Whether one plugin instance (a capability or a driver) is still in service. An exception from a lifecycle hook or a
// driver, or a handler that hangs, marks it failed once, with the first reason; it stays failed until rcand restarts
// (or its plugin is reloaded). An exception from a request handler only fails that request (docs/protocol.md §7.16):
// it is counted here and shown as the capability's handler_errors. A fault a driver reported as an sdk::DeviceFault
// keeps its device, OS error and hint beside the reason.
#pragma once

#include <atomic>
#include <cstdint>
#include <exception>
#include <mutex>
#include <string>

#include "rcand/sdk/device_fault.hpp"

namespace rcand::kernel {

// Why an instance failed: the reason for people, and for a device fault what it names (any of them may be empty).
struct Fault {
  std::string reason, device, os_error, hint;
};

// What plugin code threw, as a Fault: an sdk::DeviceFault keeps its parts apart (RTTI across the plugin boundary, as
// for the driver interfaces: the type keeps default visibility); anything else is its what().
inline Fault fault_of(const std::exception& e) {
  if (const auto* device = dynamic_cast<const sdk::DeviceFault*>(&e))
    return {device->message(), device->device(), device->os_error(), device->hint()};
  return {e.what(), {}, {}, {}};
}

class InstanceHealth {
 public:
  bool failed() const noexcept { return failed_.load(); }
  void mark_failed(std::string why) { mark_failed(Fault{std::move(why), {}, {}, {}}); }
  void mark_failed(Fault fault) {
    {
      std::lock_guard lock(mutex_);
      if (fault_.reason.empty()) fault_ = std::move(fault);
    }
    failed_.store(true);
  }
  // In service again: only for a plugin reload, once nothing of the failed instance runs any more.
  void reset() {
    std::lock_guard lock(mutex_);
    fault_ = {};
    failed_.store(false);
  }
  std::string reason() const {
    std::lock_guard lock(mutex_);
    return fault_.reason;
  }
  Fault fault() const {
    std::lock_guard lock(mutex_);
    return fault_;
  }
  // A request handler threw: that request got 500 INTERNAL; the instance stays in service.
  void count_handler_error() noexcept { handler_errors_.fetch_add(1, std::memory_order_relaxed); }
  std::uint64_t handler_errors() const noexcept { return handler_errors_.load(std::memory_order_relaxed); }

 private:
  std::atomic<bool> failed_{false};
  std::atomic<std::uint64_t> handler_errors_{0};
  mutable std::mutex mutex_;  // guards fault_ only
  Fault fault_;
};

}  // namespace rcand::kernel
