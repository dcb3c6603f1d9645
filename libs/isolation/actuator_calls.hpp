// An actuator across the process boundary: what an isolated capability's call on an actuator becomes on the channel,
// and how rcand carries it out through its motion gate. The host hands the plugin a stand-in of the actuator's
// interface whose methods send calls; rcand applies each call inside MotionGate::actuate (the latch, the actuator's
// health and its interface checked there, in rcand) or MotionGate::inspect. Interfaces carried so far:
// differential_drive and joint_arm (an actuator whose primary interface it is; the arm of a board that drives wheels
// too is not carried). Another interface is refused with WrongInterface and a log line naming it.
#pragma once

#include <nlohmann/json.hpp>

#include <functional>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>

#include "rcand/sdk/driver.hpp"
#include "rcand/sdk/motion_gate.hpp"

namespace rcand::isolation {

// A call the actuator cannot take (an unknown method, arguments of the wrong shape): its message names which.
class CallError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

// rcand's side. `method` with `args` as a command for MotionGate::actuate, checked before it reaches the gate: a call
// no interface takes (an unknown method, arguments of the wrong shape) throws CallError here, so a malformed message
// from a host never counts as the driver's failure. The command returns false for an actuator without the method's
// interface (WrongInterface, as MotionGate::actuate_as answers in process).
using ActuatorCommand = std::function<bool(sdk::ActuatorDriver&)>;
ActuatorCommand command_for(std::string_view method, const nlohmann::json& args);
// rcand's side. A reading for MotionGate::inspect ("status": Driver::status(); "joint_states"), checked likewise
// before the gate; nullopt for an actuator without the reading's interface (WrongInterface).
using ActuatorReading = std::function<std::optional<nlohmann::json>(const sdk::ActuatorDriver&)>;
ActuatorReading reading_for(std::string_view method);

// The host's side. Sends one call ("actuate" or "inspect", the method, its arguments) to rcand and returns its answer:
// {"gate": GateStatus as int, "result": ..., "error"?: why the call failed}.
using CallSender = std::function<nlohmann::json(std::string_view op, std::string_view method, nlohmann::json args)>;

// What a stand-in tells the host's gate after the plugin's command ran: the first refusal of its calls (Ok when
// none), so the command's later calls reach nothing once one was refused.
struct CallOutcome {
  sdk::GateStatus status = sdk::GateStatus::Ok;
};

// A stand-in for an actuator of `interface`, or null when that interface is not carried across yet.
std::unique_ptr<sdk::ActuatorDriver> remote_actuator(std::string_view interface, std::string_view op, CallSender send,
                                                     std::shared_ptr<CallOutcome> outcome);

}  // namespace rcand::isolation
