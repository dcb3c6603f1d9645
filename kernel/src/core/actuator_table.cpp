#include "rcand/kernel/core/actuator_table.hpp"

namespace rcand::kernel {

ActuatorSlot& ActuatorTable::add(std::string id, std::string interface, std::string plugin_id, sdk::ActuatorDriver* driver,
                                 InstanceHealth* health) {
  auto& slot = slots_.emplace_back();
  slot.id = std::move(id);
  slot.interface = std::move(interface);
  slot.plugin_id = std::move(plugin_id);
  slot.driver = driver;
  slot.health = health;
  return slot;
}

ActuatorSlot* ActuatorTable::find(std::string_view id) noexcept {
  for (auto& slot : slots_)
    if (slot.id == id) return &slot;
  return nullptr;
}

const ActuatorSlot* ActuatorTable::find(std::string_view id) const noexcept {
  for (const auto& slot : slots_)
    if (slot.id == id) return &slot;
  return nullptr;
}

std::vector<HaltReport> ActuatorTable::halt_all(const sdk::Clock& clock) noexcept {
  std::vector<HaltReport> reports;
  try {
    reports.reserve(slots_.size());
  } catch (...) {
  }
  for (auto& slot : slots_) {
    if (slot.driver == nullptr) continue;
    const auto start = clock.now_us();
    slot.driver->halt();
    try {
      reports.push_back({slot.id, true, clock.now_us() - start, "halted", {}});
    } catch (...) {  // out of memory while reporting: the halt itself already happened
    }
  }
  return reports;
}

}  // namespace rcand::kernel
