// A fake GPIO chip and PWM for tests: every request and level change goes into one ordered event log with the
// physical level (active-low applied, as the kernel would), so a test can replay the exact sequence the bridge saw
// and check invariants at every single step. Lines can be missing (by offset or name), busy, or refuse changes.
#pragma once

#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <vector>

#include "gpio_chip.hpp"
#include "pwm_output.hpp"

namespace rcand::plugins::gpio_motor::testing {

struct Event {
  std::string line;  // the line's description ("line 17"), or "pwm0.1"
  bool request;      // the line was requested now (its first level)
  bool physical;     // the level on the pin
  bool active;       // the logical level
  double duty;       // PWM events
};

class EventLog {
 public:
  void add(Event e) {
    std::lock_guard lock(mutex_);
    events_.push_back(std::move(e));
  }
  std::vector<Event> events() const {
    std::lock_guard lock(mutex_);
    return events_;
  }
  void clear() {
    std::lock_guard lock(mutex_);
    events_.clear();
  }

 private:
  mutable std::mutex mutex_;
  std::vector<Event> events_;
};

class FakeChip final : public GpioChip {
 public:
  FakeChip(std::shared_ptr<EventLog> log, unsigned lines = 54) : log_(std::move(log)), lines_(lines) {}

  std::unique_ptr<OutputLine> request_output(const LineRef& ref, bool active_low, const std::string&) override {
    const std::string name = gpio_motor::describe(ref);
    if (const auto* offset = std::get_if<unsigned>(&ref); offset && *offset >= lines_)
      throw GpioError(describe() + " has no " + name);
    if (std::holds_alternative<std::string>(ref) && !named_.count(std::get<std::string>(ref)))
      throw GpioError(describe() + " has no " + name);
    if (busy_.count(name)) throw GpioError("cannot request " + name + " of " + describe() + " as an output: busy");
    busy_.insert(name);
    log_->add({name, true, active_low, false, 0.0});  // inactive from the request on: high when active-low
    return std::make_unique<Line>(log_, name, active_low, refuse_);
  }
  std::string describe() const override { return "gpiochip0 [fake]"; }

  void add_name(std::string name) { named_.insert(std::move(name)); }
  void hold(std::string line) { busy_.insert(std::move(line)); }
  // From now on, set() on `line` fails (the kernel refusing the ioctl).
  void refuse(std::string line) { refuse_->insert(std::move(line)); }

 private:
  class Line final : public OutputLine {
   public:
    Line(std::shared_ptr<EventLog> log, std::string name, bool active_low, std::shared_ptr<std::set<std::string>> refuse)
        : log_(std::move(log)), name_(std::move(name)), active_low_(active_low), refuse_(std::move(refuse)) {}
    bool set(bool active) noexcept override {
      if (refuse_->count(name_)) return false;
      log_->add({name_, false, active != active_low_, active, 0.0});
      return true;
    }
    std::string describe() const override { return name_; }

   private:
    std::shared_ptr<EventLog> log_;
    std::string name_;
    bool active_low_;
    std::shared_ptr<std::set<std::string>> refuse_;
  };

  std::shared_ptr<EventLog> log_;
  unsigned lines_;
  std::set<std::string> named_, busy_;
  std::shared_ptr<std::set<std::string>> refuse_ = std::make_shared<std::set<std::string>>();
};

class FakePwm final : public PwmOutput {
 public:
  FakePwm(std::shared_ptr<EventLog> log, std::string name) : log_(std::move(log)), name_(std::move(name)) {}
  bool set_duty(double duty) noexcept override {
    log_->add({name_, false, duty > 0, duty > 0, duty});
    return true;
  }
  std::string describe() const override { return name_; }

 private:
  std::shared_ptr<EventLog> log_;
  std::string name_;
};

}  // namespace rcand::plugins::gpio_motor::testing
