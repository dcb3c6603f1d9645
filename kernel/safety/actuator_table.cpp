#include "kernel/safety/actuator_table.hpp"

#include <linux/futex.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <climits>
#include <ctime>
#include <thread>

namespace rcand::kernel {
namespace {

// A command that is about to return is usually microseconds away: spin that long before sleeping on the futex.
constexpr auto kCommandSpin = std::chrono::microseconds(50);

void command_exit_wait(std::atomic<std::uint32_t>& word, std::uint32_t expected, std::chrono::nanoseconds left) noexcept {
  const timespec timeout{static_cast<time_t>(left.count() / 1'000'000'000), static_cast<long>(left.count() % 1'000'000'000)};
  syscall(SYS_futex, reinterpret_cast<std::uint32_t*>(&word), FUTEX_WAIT_PRIVATE, expected, &timeout, nullptr, 0);
}

void command_exit_wake(std::atomic<std::uint32_t>& word) noexcept {
  syscall(SYS_futex, reinterpret_cast<std::uint32_t*>(&word), FUTEX_WAKE_PRIVATE, INT_MAX, nullptr, nullptr, 0);
}

// The commands the current thread is inside (nested gate calls are LIFO): a stop requested from inside a command
// (a plugin's request_estop, say) must not wait for that very command, which cannot leave before the stop returns.
struct GateCommandsOfThread {
  std::array<const ActuatorSlot*, 8> slots{};
  std::size_t depth = 0;
  std::uint32_t own(const ActuatorSlot& slot) const noexcept {
    std::uint32_t count = 0;
    for (std::size_t i = 0; i < std::min(depth, slots.size()); ++i) count += slots[i] == &slot ? 1 : 0;
    return count;
  }
};
thread_local GateCommandsOfThread t_gate_commands_of_thread;

}  // namespace

ActuatorSlot& ActuatorTable::add(std::string id, std::string interface, std::string plugin_id, sdk::ActuatorDriver* driver,
                                 InstanceHealth* health) {
  auto& slot = slots_.emplace_back();
  slot.id = std::move(id);
  slot.interface = std::move(interface);
  slot.plugin_id = std::move(plugin_id);
  slot.driver.store(driver);
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

void halt_slot(const ActuatorSlot& slot) noexcept {
  const DriverUse use(slot);
  if (use.get() != nullptr) use.get()->halt();
}

std::vector<HaltReport> ActuatorTable::halt_all(const sdk::Clock& clock) noexcept {
  std::vector<HaltReport> reports;
  try {
    reports.reserve(slots_.size());
  } catch (...) {
  }
  for (auto& slot : slots_) {
    const DriverUse use(slot);
    if (use.get() == nullptr) continue;  // its plugin is being reloaded: no driver object to halt
    const auto start = clock.now_us();
    use.get()->halt();
    try {
      reports.push_back({slot.id, true, clock.now_us() - start, "halted", {}});
    } catch (...) {  // out of memory while reporting: the halt itself already happened
    }
  }
  return reports;
}

bool ActuatorTable::retire(ActuatorSlot& slot, std::chrono::steady_clock::time_point deadline) noexcept {
  slot.driver.store(nullptr);
  // A development reload, never the stop path: polling a few milliseconds is simpler than another futex.
  while (slot.users.load() != 0) {
    if (std::chrono::steady_clock::now() >= deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return true;
}

void ActuatorTable::enter_command(ActuatorSlot& slot) noexcept {
  auto& mine = t_gate_commands_of_thread;
  if (mine.depth < mine.slots.size()) mine.slots[mine.depth] = &slot;
  ++mine.depth;
  slot.commands_in_flight.fetch_add(1);
}

void ActuatorTable::leave_command(ActuatorSlot& slot) noexcept {
  auto& mine = t_gate_commands_of_thread;
  if (mine.depth > 0) --mine.depth;
  slot.commands_in_flight.fetch_sub(1);
  command_exits_.fetch_add(1);
  // seq_cst: either this load sees the waiter, or the waiter's later check of the counters sees the decrement.
  if (exit_waiters_.load() != 0) command_exit_wake(command_exits_);
}

std::vector<std::string> ActuatorTable::wait_for_commands(std::chrono::steady_clock::time_point deadline,
                                                          const std::atomic<bool>& latched) const noexcept {
  using Clock = std::chrono::steady_clock;
  const auto& mine = t_gate_commands_of_thread;
  const auto idle = [this, &mine, &latched] {
    if (!latched.load()) return true;  // cleared meanwhile: the gate's epoch check halts the older commands
    for (const auto& slot : slots_)
      if (slot.commands_in_flight.load() > mine.own(slot)) return false;
    return true;
  };
  if (idle()) return {};  // the usual case: nothing in the gate, no wait at all
  exit_waiters_.fetch_add(1);
  const auto spin_until = std::min(deadline, Clock::now() + kCommandSpin);
  while (!idle() && Clock::now() < spin_until) {
  }
  for (;;) {
    const std::uint32_t seen = command_exits_.load();
    if (idle()) break;
    const auto left = deadline - Clock::now();
    if (left <= Clock::duration::zero()) break;
    command_exit_wait(command_exits_, seen, std::chrono::duration_cast<std::chrono::nanoseconds>(left));
  }
  exit_waiters_.fetch_sub(1);
  std::vector<std::string> busy;
  if (!latched.load()) return busy;
  try {
    for (const auto& slot : slots_)
      if (slot.commands_in_flight.load() > mine.own(slot)) busy.push_back(slot.id);
  } catch (...) {  // no memory to name them: the wait itself is done
  }
  return busy;
}

}  // namespace rcand::kernel
