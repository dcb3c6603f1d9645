// A named, single-threaded executor the kernel owns and joins at shutdown. Blocking work (a nav job, a
// serial transaction) runs here, never on an I/O thread. Tasks run one at a time in posting order.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <string_view>

#include "rcand/sdk/export.hpp"

namespace rcand::sdk {

using TimerId = std::uint64_t;

class RCAND_INTERFACE Worker {
 public:
  virtual ~Worker() = default;
  virtual std::string_view name() const noexcept = 0;
  // Any thread, never blocks. Runs `task` on this worker. Exceptions from it are caught by the kernel,
  // logged, and mark the plugin failed.
  virtual void post(std::function<void()> task) = 0;
  // Any thread, never blocks. Runs `task` on this worker after `delay` unless cancelled first.
  virtual TimerId schedule(std::chrono::microseconds delay, std::function<void()> task) = 0;
  // Any thread, never blocks. Returns true when the task was cancelled before it started.
  virtual bool cancel(TimerId id) noexcept = 0;
};

}  // namespace rcand::sdk
