// Every actuating driver instance, filled at startup and fixed afterwards, so the stop path reads it without locks.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <deque>
#include <string>
#include <vector>

#include "kernel/safety/instance_health.hpp"
#include "rcand/sdk/clock.hpp"
#include "rcand/sdk/driver.hpp"

namespace rcand::kernel {

struct ActuatorSlot {
  std::string id, interface, plugin_id;
  sdk::ActuatorDriver* driver = nullptr;  // owned by the plugin runtime, which outlives the table's users
  InstanceHealth* health = nullptr;       // the driver instance's health, shared with the runtime
  // Commands inside the motion gate for this actuator right now (KernelMotionGate: raised before the latch check,
  // lowered only after the command returned and, if a stop came meanwhile, after the gate halted the actuator).
  std::atomic<std::uint32_t> commands_in_flight{0};
};

struct HaltReport {
  std::string id;
  bool halted = false;
  std::int64_t latency_us = 0;
  std::string state = "halted";  // halted | halt_pending (did not return by the deadline) | halt_failed (threw)
  std::string error;             // why, when not halted
};

class ActuatorTable {
 public:
  // Startup only (before any request is served): registers an actuator.
  ActuatorSlot& add(std::string id, std::string interface, std::string plugin_id, sdk::ActuatorDriver* driver,
                    InstanceHealth* health);
  ActuatorSlot* find(std::string_view id) noexcept;
  const ActuatorSlot* find(std::string_view id) const noexcept;
  const std::deque<ActuatorSlot>& slots() const noexcept { return slots_; }
  // Calls halt() on every actuator directly, in registration order, failed ones too (a failed driver may still
  // move). No queue, lock or worker in between.
  std::vector<HaltReport> halt_all(const sdk::Clock& clock) noexcept;

  // The motion gate's bookkeeping of commands in flight (seq_cst, lock-free): enter before the latch check,
  // leave after the command (and the gate's own halt). leave() wakes a stop waiting in wait_for_commands().
  void enter_command(ActuatorSlot& slot) noexcept;
  void leave_command(ActuatorSlot& slot) noexcept;
  // The stop path, after latching: waits until no actuator has a command in flight, or until `deadline`, on a
  // futex (never on a lock a command holds), or until `latched` is cleared. Commands the calling thread is itself
  // inside do not count. Returns the ids of the actuators that still have one at the deadline.
  std::vector<std::string> wait_for_commands(std::chrono::steady_clock::time_point deadline,
                                             const std::atomic<bool>& latched) const noexcept;
  // How many stops are inside wait_for_commands right now (observability and tests).
  std::uint32_t stops_waiting() const noexcept { return exit_waiters_.load(); }

 private:
  std::deque<ActuatorSlot> slots_;                       // deque: slots never move, so pointers stay valid
  mutable std::atomic<std::uint32_t> command_exits_{0};  // bumped by every leave_command (the futex word)
  mutable std::atomic<std::uint32_t> exit_waiters_{0};   // stops waiting in wait_for_commands
};

}  // namespace rcand::kernel
