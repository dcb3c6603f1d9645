// Collects what a transport delivers, for tests: thread-safe, with a bounded wait for a condition (no sleeps).
// The delivery callback shares ownership of the state, so a transport's thread may still deliver after the Inbox
// itself is gone (tests declare transports and inboxes in either order).
#pragma once

#include <chrono>
#include <condition_variable>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <vector>

#include "services/r2r/transport.hpp"

namespace rcand::test {

class Inbox {
 public:
  rcand::services::r2r::Deliver deliver() {
    return [state = state_](rcand::services::r2r::InboundMessage message) {
      std::lock_guard lock(state->mutex);
      state->messages.push_back(std::move(message));
      state->changed.notify_all();
    };
  }
  // Waits until `count` messages arrived (or the deadline); returns a copy of what is there.
  std::vector<rcand::services::r2r::InboundMessage> wait_for(std::size_t count,
                                                             std::chrono::milliseconds timeout = std::chrono::seconds(5)) {
    std::unique_lock lock(state_->mutex);
    state_->changed.wait_for(lock, timeout, [&] { return state_->messages.size() >= count; });
    return state_->messages;
  }
  // Waits until some delivered message satisfies `match`; returns it (nullopt at the deadline).
  std::optional<rcand::services::r2r::InboundMessage> wait_until(
      const std::function<bool(const rcand::services::r2r::InboundMessage&)>& match,
      std::chrono::milliseconds timeout = std::chrono::seconds(5)) {
    std::unique_lock lock(state_->mutex);
    std::optional<rcand::services::r2r::InboundMessage> found;
    state_->changed.wait_for(lock, timeout, [&] {
      for (const auto& message : state_->messages)
        if (match(message)) {
          found = message;
          return true;
        }
      return false;
    });
    return found;
  }
  std::size_t size() {
    std::lock_guard lock(state_->mutex);
    return state_->messages.size();
  }

 private:
  struct State {
    std::mutex mutex;
    std::condition_variable changed;
    std::vector<rcand::services::r2r::InboundMessage> messages;
  };
  std::shared_ptr<State> state_ = std::make_shared<State>();
};

}  // namespace rcand::test
