// Every actuating driver instance, filled at startup and fixed afterwards, so the stop path reads it without locks.
#pragma once

#include <cstdint>
#include <deque>
#include <string>
#include <vector>

#include "rcand/kernel/core/instance_health.hpp"
#include "rcand/sdk/clock.hpp"
#include "rcand/sdk/driver.hpp"

namespace rcand::kernel {

struct ActuatorSlot {
  std::string id, interface, plugin_id;
  sdk::ActuatorDriver* driver = nullptr;  // owned by the plugin runtime, which outlives the table's users
  InstanceHealth* health = nullptr;       // the driver instance's health, shared with the runtime
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

 private:
  std::deque<ActuatorSlot> slots_;  // deque: slots never move, so pointers stay valid
};

}  // namespace rcand::kernel
