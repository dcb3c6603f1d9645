// Publishes a plugin's status while it changes (PluginContext::publish_status, ABI 1.1), from the context's "status"
// worker: changed() from any thread after a change; the publisher sends a snapshot at once, then every `period`
// while the snapshot says the hardware moves or its version moved since the last one sent, and stops after sending
// the state at rest. The status board then shows motion as it happens instead of at its next poll of status().
// Without a context (a unit test's bare object) nothing is published. Header-only: no ABI of its own.
//
// The owner keeps it alive until its context's workers are joined (the kernel joins them before destroying the
// driver or capability that owns it); the snapshot callable runs on the "status" worker.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <utility>

#include "rcand/sdk/context.hpp"
#include "rcand/sdk/worker.hpp"

namespace rcand::sdk {

class StatusPublisher {
 public:
  struct Snapshot {
    Json status;
    std::uint64_t version = 0;  // bumped by the owner on every change it wants published
    bool moving = false;        // keep publishing every period while true
  };
  // `version` reads the current version alone (cheap); `snapshot` the status with the version it shows.
  StatusPublisher(PluginContext* context, std::chrono::microseconds period, std::function<Snapshot()> snapshot,
                  std::function<std::uint64_t()> version)
      : context_(context),
        worker_(context != nullptr ? &context->worker("status") : nullptr),
        period_(period),
        snapshot_(std::move(snapshot)),
        version_(std::move(version)) {}
  StatusPublisher(const StatusPublisher&) = delete;
  StatusPublisher& operator=(const StatusPublisher&) = delete;

  // Any thread, never blocks: starts publishing unless it runs already (then the running one picks the change up).
  void changed() noexcept {
    if (worker_ == nullptr || publishing_.exchange(true)) return;
    try {
      worker_->post([this] { tick(); });
    } catch (...) {  // no memory for the task: the kernel asks status() itself within a second or two
      publishing_ = false;
    }
  }

 private:
  void tick() noexcept {
    Snapshot now;
    try {
      now = snapshot_();
    } catch (...) {
      publishing_ = false;
      return;
    }
    context_->publish_status(now.status);
    const auto more = [&] {
      try {
        return now.moving || version_() != now.version;
      } catch (...) {
        return false;
      }
    };
    if (more()) {
      try {
        worker_->schedule(period_, [this] { tick(); });
        return;
      } catch (...) {
      }
    }
    publishing_ = false;
    // A change between more() and the store above found publishing_ still set and left it to this tick.
    if (more()) changed();
  }

  PluginContext* const context_;
  Worker* const worker_;  // the context's "status" worker; null without a context
  const std::chrono::microseconds period_;
  const std::function<Snapshot()> snapshot_;
  const std::function<std::uint64_t()> version_;
  std::atomic<bool> publishing_{false};  // a tick is queued or scheduled
};

}  // namespace rcand::sdk
