// Holds a capability's requests out while its plugin is reloaded (they get 503), and lets the reload wait until the
// calls admitted before have finished. Any thread.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <memory>
#include <mutex>

namespace rcand {

class ReloadGate : public std::enable_shared_from_this<ReloadGate> {
 public:
  // Held by one admitted call until its handler has returned (captured by the task that runs it).
  using Pass = std::shared_ptr<const void>;

  // A pass while open; null while a reload holds the gate closed.
  Pass enter() {
    std::lock_guard lock(mutex_);
    if (closed_) return nullptr;
    ++inside_;
    return Pass(this, [gate = shared_from_this()](const void*) { gate->leave(); });
  }
  // Closes, then waits up to `within` for every pass to be given back. False: a call is still running.
  bool close_and_drain(std::chrono::milliseconds within) {
    std::unique_lock lock(mutex_);
    closed_ = true;
    return drained_.wait_for(lock, within, [this] { return inside_ == 0; });
  }
  void open() {
    std::lock_guard lock(mutex_);
    closed_ = false;
  }

 private:
  void leave() {
    std::lock_guard lock(mutex_);
    if (--inside_ == 0) drained_.notify_all();
  }
  std::mutex mutex_;
  std::condition_variable drained_;
  std::size_t inside_ = 0;
  bool closed_ = false;
};

}  // namespace rcand
