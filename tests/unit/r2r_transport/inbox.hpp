// Collects what a transport delivers, for tests: thread-safe, with a bounded wait for a condition (no sleeps).
#pragma once

#include <chrono>
#include <condition_variable>
#include <functional>
#include <mutex>
#include <optional>
#include <vector>

#include "rcand/kernel/r2r/transport.hpp"

namespace rcand::test {

class Inbox {
 public:
  rcand::kernel::r2r::Deliver deliver() {
    return [this](rcand::kernel::r2r::InboundMessage message) {
      std::lock_guard lock(mutex_);
      messages_.push_back(std::move(message));
      changed_.notify_all();
    };
  }
  // Waits until `count` messages arrived (or the deadline); returns a copy of what is there.
  std::vector<rcand::kernel::r2r::InboundMessage> wait_for(std::size_t count,
                                                           std::chrono::milliseconds timeout = std::chrono::seconds(5)) {
    std::unique_lock lock(mutex_);
    changed_.wait_for(lock, timeout, [&] { return messages_.size() >= count; });
    return messages_;
  }
  // Waits until some delivered message satisfies `match`; returns it (nullopt at the deadline).
  std::optional<rcand::kernel::r2r::InboundMessage> wait_until(
      const std::function<bool(const rcand::kernel::r2r::InboundMessage&)>& match,
      std::chrono::milliseconds timeout = std::chrono::seconds(5)) {
    std::unique_lock lock(mutex_);
    std::optional<rcand::kernel::r2r::InboundMessage> found;
    changed_.wait_for(lock, timeout, [&] {
      for (const auto& message : messages_)
        if (match(message)) {
          found = message;
          return true;
        }
      return false;
    });
    return found;
  }
  std::size_t size() {
    std::lock_guard lock(mutex_);
    return messages_.size();
  }

 private:
  std::mutex mutex_;
  std::condition_variable changed_;
  std::vector<rcand::kernel::r2r::InboundMessage> messages_;
};

}  // namespace rcand::test
