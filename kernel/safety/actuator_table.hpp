// Every actuating driver instance, filled at startup and fixed afterwards, so the stop path reads it without locks.
// Only a slot's driver object changes, when a development reload replaces its plugin (retire, then install).
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
  InstanceHealth* health = nullptr;  // the driver instance's health, shared with the runtime
  // Owned by the plugin runtime; null while a reload replaces it. Read only through a DriverUse.
  std::atomic<sdk::ActuatorDriver*> driver{nullptr};
  mutable std::atomic<std::uint32_t> users{0};  // DriverUses alive: a retired driver is destroyed only at zero
  // Commands inside the motion gate for this actuator right now (KernelMotionGate: raised before the latch check,
  // lowered only after the command returned and, if a stop came meanwhile, after the gate halted the actuator).
  std::atomic<std::uint32_t> commands_in_flight{0};
};

// Holds a slot's driver for the length of one call (seq_cst, lock-free, so the stop path uses it too): counted
// before the pointer is read, so a reload that retired the driver either is seen here as null or sees this use.
class DriverUse {
 public:
  explicit DriverUse(const ActuatorSlot& slot) noexcept : slot_(slot) {
    slot_.users.fetch_add(1);
    driver_ = slot_.driver.load();
  }
  ~DriverUse() { slot_.users.fetch_sub(1); }
  DriverUse(const DriverUse&) = delete;
  DriverUse& operator=(const DriverUse&) = delete;
  sdk::ActuatorDriver* get() const noexcept { return driver_; }  // null while its plugin reloads

 private:
  const ActuatorSlot& slot_;
  sdk::ActuatorDriver* driver_;
};

// halt() on the slot's driver, if it has one right now.
void halt_slot(const ActuatorSlot& slot) noexcept;

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
  // A plugin reload, with the e-stop latched: the slot's driver is taken out (the gate answers ActuatorFailed, halts
  // skip it), then waited for until no call uses it or `deadline` passes. False: a call into it still runs, so the
  // old object must never be destroyed.
  static bool retire(ActuatorSlot& slot, std::chrono::steady_clock::time_point deadline) noexcept;
  // The reload's new driver object, in service from here on.
  static void install(ActuatorSlot& slot, sdk::ActuatorDriver* driver) noexcept { slot.driver.store(driver); }

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
