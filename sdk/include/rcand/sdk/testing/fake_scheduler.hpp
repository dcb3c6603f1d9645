// Workers that never start a thread. Posted tasks and timers wait in one queue ordered by (due time, posting
// order) and run only when the test calls run_due() / run_until(), on the test's thread, so every
// interleaving a test sees is one it chose.
#pragma once

#include <chrono>
#include <cstdint>
#include <exception>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <tuple>
#include <utility>

#include "rcand/sdk/testing/manual_clock.hpp"
#include "rcand/sdk/worker.hpp"

namespace rcand::sdk::testing {

class FakeScheduler {
 public:
  // Called with the worker's name and the message when a task throws (the kernel logs it and marks the
  // plugin failed; the fake host does the same).
  using FailureHandler = std::function<void(const std::string& worker, const std::string& what)>;

  explicit FakeScheduler(ManualClock& clock) : clock_(clock) {}

  TimerId enqueue(std::string worker, std::int64_t due_us, std::function<void()> task) {
    std::lock_guard lock(mutex_);
    const TimerId id = next_id_++;
    queue_.emplace(Key{due_us, id}, Entry{std::move(worker), std::move(task)});
    return id;
  }

  bool cancel(TimerId id) noexcept {
    std::lock_guard lock(mutex_);
    if (cancel_race_) return false;  // the task "already started": it will still run
    for (auto it = queue_.begin(); it != queue_.end(); ++it)
      if (it->first.id == id) {
        queue_.erase(it);
        return true;
      }
    return false;
  }

  // Simulates the race a threaded kernel allows: cancel() loses because the timer already fired on the
  // worker thread. While on, cancel() returns false and the task still runs when due.
  void set_cancel_race(bool on) noexcept {
    std::lock_guard lock(mutex_);
    cancel_race_ = on;
  }

  void on_failure(FailureHandler handler) { on_failure_ = std::move(handler); }

  // The earliest queued due time, if any.
  std::optional<std::int64_t> next_due() const {
    std::lock_guard lock(mutex_);
    if (queue_.empty()) return std::nullopt;
    return queue_.begin()->first.due_us;
  }

  // Runs, in order, every task due at or before the clock's current time, including tasks they post.
  // Returns how many ran.
  std::size_t run_due() {
    std::size_t ran = 0;
    while (run_one(clock_.now_us())) ++ran;
    return ran;
  }

  // Runs one task due at or before `limit_us`, moving the clock to its due time first. False when none is due.
  bool run_one(std::int64_t limit_us) {
    std::string worker;
    std::function<void()> task;
    {
      std::lock_guard lock(mutex_);
      if (queue_.empty() || queue_.begin()->first.due_us > limit_us) return false;
      auto node = queue_.extract(queue_.begin());
      clock_.set_us(node.key().due_us);
      worker = std::move(node.mapped().worker);
      task = std::move(node.mapped().task);
    }
    try {
      task();
    } catch (const std::exception& e) {
      if (on_failure_) on_failure_(worker, e.what());
    } catch (...) {
      if (on_failure_) on_failure_(worker, "unknown exception");
    }
    return true;
  }

  // Drops every queued task without running it (the host does this before destroying plugin objects).
  void clear() {
    std::multimap<Key, Entry> dropped;
    {
      std::lock_guard lock(mutex_);
      dropped.swap(queue_);
    }
  }

  std::size_t size() const {
    std::lock_guard lock(mutex_);
    return queue_.size();
  }

 private:
  struct Key {
    std::int64_t due_us;
    TimerId id;  // ids grow with posting order, so equal due times run first-posted first
    bool operator<(const Key& other) const { return std::tie(due_us, id) < std::tie(other.due_us, other.id); }
  };
  struct Entry {
    std::string worker;
    std::function<void()> task;
  };

  ManualClock& clock_;
  mutable std::mutex mutex_;
  std::multimap<Key, Entry> queue_;
  TimerId next_id_ = 1;
  bool cancel_race_ = false;
  FailureHandler on_failure_;
};

class FakeWorker final : public Worker {
 public:
  FakeWorker(FakeScheduler& scheduler, const ManualClock& clock, std::string name)
      : scheduler_(scheduler), clock_(clock), name_(std::move(name)) {}
  std::string_view name() const noexcept override { return name_; }
  void post(std::function<void()> task) override { scheduler_.enqueue(name_, clock_.now_us(), std::move(task)); }
  TimerId schedule(std::chrono::microseconds delay, std::function<void()> task) override {
    const std::int64_t delay_us = delay.count() < 0 ? 0 : delay.count();
    return scheduler_.enqueue(name_, clock_.now_us() + delay_us, std::move(task));
  }
  bool cancel(TimerId id) noexcept override { return scheduler_.cancel(id); }

 private:
  FakeScheduler& scheduler_;
  const ManualClock& clock_;
  std::string name_;
};

}  // namespace rcand::sdk::testing
