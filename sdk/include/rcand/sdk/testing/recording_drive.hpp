// A DifferentialDrive that only records what it was told, for testing capabilities without a real driver:
//   auto& drive = host.add_driver_instance<RecordingDrive>("base", host.clock());
#pragma once

#include <cstdint>
#include <functional>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

#include "rcand/sdk/clock.hpp"
#include "rcand/sdk/driver.hpp"

namespace rcand::sdk::testing {

class RecordingDrive final : public DifferentialDrive {
 public:
  struct Event {
    std::int64_t t_us;
    double left;
    double right;
    bool halt;  // true: halt(); false: set_wheel_speeds()
  };

  explicit RecordingDrive(const Clock& clock) : clock_(clock) {}

  void set_wheel_speeds(double left, double right) override {
    std::function<void()> hook;
    {
      std::lock_guard lock(mutex_);
      hook = on_command_;
      if (fail_next_) {
        fail_next_ = false;
        throw std::runtime_error("recording drive: injected failure");
      }
    }
    if (hook) hook();  // runs outside the lock: it may halt this drive (an e-stop racing the command)
    std::lock_guard lock(mutex_);
    left_ = left;
    right_ = right;
    events_.push_back({clock_.now_us(), left, right, false});
  }

  void halt() noexcept override {
    std::lock_guard lock(mutex_);
    left_ = right_ = 0.0;
    try {
      events_.push_back({clock_.now_us(), 0.0, 0.0, true});
    } catch (...) {  // out of memory: the wheels are stopped anyway
    }
  }

  // The next set_wheel_speeds() throws std::runtime_error and records nothing.
  void fail_next() {
    std::lock_guard lock(mutex_);
    fail_next_ = true;
  }
  // Called inside every set_wheel_speeds() before it records, e.g. to latch the e-stop mid-command.
  void on_command(std::function<void()> hook) {
    std::lock_guard lock(mutex_);
    on_command_ = std::move(hook);
  }

  std::vector<Event> events() const {
    std::lock_guard lock(mutex_);
    return events_;
  }
  std::vector<Event> commands() const {
    std::vector<Event> out;
    for (const auto& e : events())
      if (!e.halt) out.push_back(e);
    return out;
  }
  double left() const {
    std::lock_guard lock(mutex_);
    return left_;
  }
  double right() const {
    std::lock_guard lock(mutex_);
    return right_;
  }
  bool moving() const {
    std::lock_guard lock(mutex_);
    return left_ != 0.0 || right_ != 0.0;
  }

 private:
  const Clock& clock_;
  mutable std::mutex mutex_;
  double left_ = 0.0;
  double right_ = 0.0;
  bool fail_next_ = false;
  std::function<void()> on_command_;
  std::vector<Event> events_;
};

}  // namespace rcand::sdk::testing
