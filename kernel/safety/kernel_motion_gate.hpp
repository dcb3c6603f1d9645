// The one door to the motors (sdk::MotionGate), implemented without locks on the command path:
// read the latch epoch and check the latch, run the command, then check both again and halt if a stop came
// meanwhile. Because the stop path bumps the epoch and latches before it halts, every interleaving ends with the
// actuator halted. Each command is also counted in flight for its actuator (raised before the latch check, lowered
// after the command and the gate's halt), so Estop::latch can wait, bounded, until every command that got past the
// check before the latch has left: after latch() returns no command reaches a driver (see Estop::latch). The stop
// never waits on a lock: the count is an atomic, the wait a futex.
#pragma once

#include "kernel/safety/actuator_table.hpp"
#include "kernel/safety/estop.hpp"
#include "rcand/sdk/motion_gate.hpp"

namespace rcand::kernel {

class KernelMotionGate final : public sdk::MotionGate {
 public:
  KernelMotionGate(ActuatorTable& actuators, Estop& estop) : actuators_(actuators), estop_(estop) {}

  sdk::GateStatus actuate(std::string_view actuator_id, const std::function<void(sdk::ActuatorDriver&)>& command) override;
  void halt(std::string_view actuator_id) noexcept override;
  std::vector<sdk::ActuatorInfo> actuators() const override;
  sdk::GateStatus inspect(std::string_view actuator_id,
                          const std::function<void(const sdk::ActuatorDriver&)>& reader) const override;

 private:
  ActuatorTable& actuators_;
  Estop& estop_;
};

}  // namespace rcand::kernel
