// The kernel's one door to the motors. Every motion path (teleop, nav, arm, chat, swarm, R2R) calls
// actuate(); while the e-stop is latched it refuses and the driver receives nothing.
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "rcand/sdk/driver.hpp"
#include "rcand/sdk/http.hpp"

namespace rcand::sdk {

enum class GateStatus {
  Ok,
  EstopActive,       // refused: the e-stop is latched
  UnknownActuator,   // no actuator with that id
  WrongInterface,    // the actuator does not implement the requested interface
  ActuatorFailed,    // the driver threw earlier (or now) and is out of service
};

struct ActuatorInfo {
  std::string id;         // the driver's `id` in the robot config
  std::string interface;  // ActuatorDriver::interface_name()
};

class RCAND_INTERFACE MotionGate {
 public:
  virtual ~MotionGate() = default;
  // Handler or worker thread. Runs `command` on the actuator unless the e-stop is latched. If the e-stop
  // latches while `command` runs, the gate halts the actuator again after it returns, so a command racing a
  // stop never leaves a motor running. Blocks only as long as `command` does.
  virtual GateStatus actuate(std::string_view actuator_id, const std::function<void(ActuatorDriver&)>& command) = 0;
  // Any thread, never refused: stopping is always allowed (used for non-latching stops and dead-man expiry).
  virtual void halt(std::string_view actuator_id) noexcept = 0;
  // Any thread, never blocks.
  virtual std::vector<ActuatorInfo> actuators() const = 0;
  // Handler or worker thread. Reads an actuator's state; never refused by the e-stop, because reading moves
  // nothing (the reader gets a const reference). UnknownActuator / ActuatorFailed as for actuate().
  virtual GateStatus inspect(std::string_view actuator_id, const std::function<void(const ActuatorDriver&)>& reader) const = 0;

  // The first actuator implementing `interface`, if any.
  std::optional<std::string> first_actuator(std::string_view interface) const {
    for (auto& info : actuators())
      if (info.interface == interface) return info.id;
    return std::nullopt;
  }

  // actuate() with the actuator viewed as T (for example DifferentialDrive).
  template <class T, class F> GateStatus actuate_as(std::string_view actuator_id, F&& command) {
    bool wrong_interface = false;
    const GateStatus status = actuate(actuator_id, [&](ActuatorDriver& actuator) {
      if (auto* typed = dynamic_cast<T*>(&actuator)) command(*typed);
      else wrong_interface = true;
    });
    return wrong_interface ? GateStatus::WrongInterface : status;
  }

  // inspect() with the actuator viewed as const T.
  template <class T, class F> GateStatus inspect_as(std::string_view actuator_id, F&& reader) const {
    bool wrong_interface = false;
    const GateStatus status = inspect(actuator_id, [&](const ActuatorDriver& actuator) {
      if (auto* typed = dynamic_cast<const T*>(&actuator)) reader(*typed);
      else wrong_interface = true;
    });
    return wrong_interface ? GateStatus::WrongInterface : status;
  }
};

// The HTTP answer for a refused gate call (docs/protocol.md §4 and §6).
inline Response gate_refusal(GateStatus status, std::string_view actuator_id) {
  const std::string id(actuator_id);
  switch (status) {
    case GateStatus::Ok: return Response::ok();
    case GateStatus::EstopActive:
      return Response::error(423, "ESTOP_ACTIVE", "e-stop is latched; clear it with POST /api/estop/clear");
    case GateStatus::UnknownActuator:
      return Response::error(503, "UNAVAILABLE", "no actuator '" + id + "' is configured");
    case GateStatus::WrongInterface:
      return Response::error(503, "UNAVAILABLE", "actuator '" + id + "' does not implement the needed interface");
    case GateStatus::ActuatorFailed:
      return Response::error(503, "UNAVAILABLE", "actuator '" + id + "' has failed and is out of service");
  }
  return Response::error(500, "INTERNAL", "unknown gate status");
}

}  // namespace rcand::sdk
