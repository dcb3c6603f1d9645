#include "kernel/safety/kernel_motion_gate.hpp"

#include "libs/base/logging.hpp"

namespace rcand::kernel {

sdk::GateStatus KernelMotionGate::actuate(std::string_view actuator_id,
                                          const std::function<void(sdk::ActuatorDriver&)>& command) {
  ActuatorSlot* slot = actuators_.find(actuator_id);
  if (slot == nullptr) return sdk::GateStatus::UnknownActuator;
  const DriverUse use(*slot);  // its driver stays alive until this returns, even when a reload retires it
  sdk::ActuatorDriver* driver = use.get();
  if (driver == nullptr || (slot->health != nullptr && slot->health->failed())) return sdk::GateStatus::ActuatorFailed;
  // Counted in flight BEFORE the latch check (both seq_cst): a stop either sees this command in flight and waits
  // for it to leave, or this check sees the latch. The count drops only after the command returned and, when a
  // stop came meanwhile, after the halt below (leaving is the destructor: every return path, exceptions too).
  struct LeaveGateOnExit {
    ActuatorTable& table;
    ActuatorSlot& slot;
    ~LeaveGateOnExit() { table.leave_command(slot); }
  };
  actuators_.enter_command(*slot);
  const LeaveGateOnExit in_flight{actuators_, *slot};
  const auto epoch = estop_.epoch();
  if (estop_.latched()) return sdk::GateStatus::EstopActive;
  try {
    command(*driver);
  } catch (const std::exception& e) {
    driver->halt();
    if (slot->health) slot->health->mark_failed(fault_of(e));
    logger("kernel.motion")->error("actuator {} ({}) threw: {}; halted and out of service", slot->id, slot->plugin_id, e.what());
    return sdk::GateStatus::ActuatorFailed;
  } catch (...) {
    driver->halt();
    if (slot->health) slot->health->mark_failed("non-standard exception");
    logger("kernel.motion")->error("actuator {} ({}) threw a non-standard exception; halted", slot->id, slot->plugin_id);
    return sdk::GateStatus::ActuatorFailed;
  }
  // A stop that latched while the command ran may have halted before the command took effect: halt again, also
  // when that stop was already cleared (the epoch moved) — a command older than a stop never outlives it.
  if (estop_.latched() || estop_.epoch() != epoch) {
    driver->halt();
    return sdk::GateStatus::EstopActive;
  }
  return sdk::GateStatus::Ok;
}

void KernelMotionGate::halt(std::string_view actuator_id) noexcept {
  if (const ActuatorSlot* slot = actuators_.find(actuator_id); slot != nullptr) halt_slot(*slot);
}

sdk::GateStatus KernelMotionGate::inspect(std::string_view actuator_id,
                                          const std::function<void(const sdk::ActuatorDriver&)>& reader) const {
  const ActuatorSlot* slot = actuators_.find(actuator_id);
  if (slot == nullptr) return sdk::GateStatus::UnknownActuator;
  const DriverUse use(*slot);
  if (use.get() == nullptr || (slot->health != nullptr && slot->health->failed())) return sdk::GateStatus::ActuatorFailed;
  reader(*use.get());  // the caller's worker guards exceptions; reading cannot leave anything moving
  return sdk::GateStatus::Ok;
}

std::vector<sdk::ActuatorInfo> KernelMotionGate::actuators() const {
  std::vector<sdk::ActuatorInfo> list;
  for (const auto& slot : actuators_.slots()) list.push_back({slot.id, slot.interface});
  return list;
}

}  // namespace rcand::kernel
