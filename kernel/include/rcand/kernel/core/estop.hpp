// The latched e-stop (notes §6). The stop path latches first (one atomic exchange), then halts every actuator
// directly, then wakes sleeping jobs and runs the on-latch listeners. It shares no queue, lock or worker with
// capability handlers: handlers only ever load the atomic.
#pragma once

#include <atomic>
#include <condition_variable>
#include <functional>
#include <mutex>
#include <string>
#include <vector>

#include "rcand/kernel/core/actuator_table.hpp"
#include "rcand/sdk/estop_view.hpp"

namespace rcand::kernel {

class Estop final : public sdk::EstopView {
 public:
  struct StopReport {
    bool newly_latched = false;
    std::vector<HaltReport> drivers;
    std::int64_t latency_us = 0;  // from entering latch() to every actuator confirmed halted
  };
  struct Snapshot {
    bool estopped = false;
    std::int64_t since_ms = 0;
    std::string reason, source;
  };

  Estop(const sdk::Clock& clock, ActuatorTable& actuators);

  bool latched() const noexcept override { return latched_.load(); }
  // Counts latches. A command that sees it change while it runs was overtaken by a stop, even one already cleared.
  std::uint64_t epoch() const noexcept { return epoch_.load(); }
  bool sleep_unless_latched(std::chrono::microseconds duration) const override;
  void request_estop(const std::string& reason) noexcept override;

  // Any thread. Latches (a repeated stop re-halts but keeps the first reason and time) and halts every actuator.
  StopReport latch(const std::string& reason, const std::string& source) noexcept;
  // Returns true when it was latched.
  bool clear();
  Snapshot snapshot() const;
  // Startup only. Listeners run on the stop path after the halt (they cancel jobs) and must not block.
  void on_latched(std::function<void()> listener);

 private:
  const sdk::Clock& clock_;
  ActuatorTable& actuators_;
  std::atomic<bool> latched_{false};
  std::atomic<std::uint64_t> epoch_{0};
  mutable std::mutex info_mutex_;  // reason/source/since, read by GET /api/estop
  Snapshot info_;
  mutable std::mutex sleep_mutex_;  // only for sleepers' condition variable
  mutable std::condition_variable sleepers_;
  std::vector<std::function<void()>> listeners_;
};

}  // namespace rcand::kernel
