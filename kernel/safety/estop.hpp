// The latched e-stop (docs/protocol.md §6). The stop path latches first (one atomic exchange), then halts every actuator, then
// wakes sleeping jobs and runs the on-latch listeners. It shares no queue, lock or worker with capability handlers:
// handlers only ever load the atomic. Once the halt crew is installed, the actuators' halt() calls run on its
// pre-created threads (a leader in turn; a driver's own thread past the crew's 200 µs hand-off) and the stop waits for
// them only up to kHaltDeadline: a slow, hung or throwing driver is reported (halt_pending / halt_failed) and delays
// neither the answer nor (beyond the hand-off) the other drivers' halts.
#pragma once

#include <atomic>
#include <condition_variable>
#include <functional>
#include <mutex>
#include <string>
#include <vector>

#include "kernel/safety/actuator_table.hpp"
#include "libs/base/deadline_crew.hpp"
#include "libs/base/stop_origin.hpp"
#include "rcand/sdk/estop_view.hpp"

namespace rcand::kernel {

class Estop final : public sdk::EstopView {
 public:
  // How long a stop waits for the drivers' halt() calls. With a swarm broadcast's 300 ms per-peer timeout after it,
  // a broadcast stop stays inside the 500 ms limit (docs/protocol.md §6, §9) even with a driver that never returns.
  static constexpr std::chrono::milliseconds kHaltDeadline{100};

  struct StopReport {
    bool newly_latched = false;
    std::vector<HaltReport> drivers;
    std::int64_t latency_us = 0;  // from entering latch() to every actuator confirmed halted
    // Actuators with a command that got into the motion gate before the latch and had not left it by the deadline
    // (their entry in `drivers` says so too: not halted, state "command_in_flight").
    std::vector<std::string> commands_in_flight;
    std::string shown_reason, shown_source;  // a new latch's, as recorded (bounded): announce()'s log line
  };
  // Runs announce() when it goes out of scope, whatever the caller's answer did in between (threw, say).
  struct Announcement {
    Estop& estop;
    StopReport report;
    ~Announcement() { estop.announce(report); }
  };
  using Origin = StopOrigin;  // who stopped the robot and how (docs/protocol.md §6.7)
  struct Snapshot {
    bool estopped = false;
    std::int64_t since_ms = 0;
    std::string reason, source;
    Origin origin;
  };

  Estop(const sdk::Clock& clock, ActuatorTable& actuators);

  bool latched() const noexcept override { return latched_.load(); }
  // Counts latches. A command that sees it change while it runs was overtaken by a stop, even one already cleared.
  std::uint64_t epoch() const noexcept { return epoch_.load(); }
  bool sleep_unless_latched(std::chrono::microseconds duration) const override;
  void request_estop(const std::string& reason) noexcept override;

  // Any thread. Latches (a repeated stop re-halts but keeps the first reason and time) and halts every actuator.
  //
  // Ordering guarantee: once latch() returns, no motion command reaches a driver until the latch is cleared. The
  // motion gate counts each command in flight before it checks the latch (both seq_cst), so a command either sees
  // the latch and never calls the driver, or is counted; latch() sets the flag, halts every actuator, then waits
  // (lock-free, on a futex; together with the halts at most kHaltDeadline) until no counted command is left in the
  // gate. A command leaves only after it returned and the gate, seeing the latch, halted its actuator again, so
  // each driver's last call is a halt. The stop's answer is sent after latch() returns. A command still in the
  // gate at the deadline (a driver call that hangs) is named in the report (commands_in_flight, and its driver
  // entry is "command_in_flight"): for it the guarantee is only that the gate halts the actuator when it returns.
  // A stop requested from inside a command (request_estop) does not wait for the command it is called from. If the
  // latch is cleared while latch() waits, the wait ends (the gate still halts every command older than the stop).
  // `origin` is recorded with the reason, before the halt (so anyone who sees a motor stop can read why).
  StopReport latch(const std::string& reason, const std::string& source, const Origin& origin = {}) noexcept;
  // latch() in two steps, for a caller that answers in between (POST /api/stop): latch_unannounced() latches, halts,
  // waits for commands in flight and records the reason, as latch() does; announce() then runs the on-latch listeners
  // and logs a new latch. The answer then waits for no listener's wake-up (each one a cross-CPU wake-up that the
  // answer paid for before). announce() must follow: hold the report in an Announcement.
  StopReport latch_unannounced(const std::string& reason, const std::string& source, const Origin& origin = {}) noexcept;
  void announce(const StopReport& report) noexcept;
  // Returns true when it was latched.
  bool clear();
  // Startup only, while latched: replaces the reason and source shown (rcand starts latched for several causes);
  // the origin becomes "startup".
  void restate(std::string reason, std::string source);
  Snapshot snapshot() const;
  // Startup only. Listeners run on the stop path after the halt (they cancel jobs; after the answer for POST
  // /api/stop) and must not block.
  void on_latched(std::function<void()> listener);
  // Startup only. Run by clear() after the latch was released (the state dir's record follows it).
  void on_cleared(std::function<void()> listener);
  // Startup, once the actuators are registered: halts go through `crew` (one job per actuator, named by its id)
  // from then on; nullptr (the default, and at shutdown) halts inline, in order. The crew outlives its use here.
  void use_halt_crew(DeadlineCrew* crew) noexcept { halt_crew_.store(crew); }

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
  std::vector<std::function<void()>> clear_listeners_;
  std::atomic<DeadlineCrew*> halt_crew_{nullptr};

  std::vector<HaltReport> halt_everything(std::chrono::steady_clock::time_point deadline) noexcept;
};

}  // namespace rcand::kernel
