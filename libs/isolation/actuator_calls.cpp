#include "libs/isolation/actuator_calls.hpp"

#include <utility>
#include <vector>

#include "rcand/sdk/interfaces/arm.hpp"

namespace rcand::isolation {

namespace {

double number_at(const nlohmann::json& args, std::size_t index, std::string_view method) {
  if (!args.is_array() || index >= args.size() || !args[index].is_number())
    throw CallError(std::string(method) + ": argument " + std::to_string(index) + " must be a number");
  return args[index].get<double>();
}

// The calls every stand-in makes, and the refusal it remembers.
class Caller {
 public:
  Caller(std::string_view op, CallSender send, std::shared_ptr<CallOutcome> outcome)
      : op_(op), send_(std::move(send)), outcome_(std::move(outcome)) {}
  nlohmann::json call(std::string_view method, nlohmann::json args) const {
    if (outcome_->status != sdk::GateStatus::Ok) return nullptr;  // refused once: the rest of the command moves nothing
    const nlohmann::json answer = send_(op_, method, std::move(args));
    const auto gate = static_cast<sdk::GateStatus>(answer.value("gate", static_cast<int>(sdk::GateStatus::ActuatorFailed)));
    if (gate != sdk::GateStatus::Ok) outcome_->status = gate;
    if (const auto error = answer.find("error"); error != answer.end() && error->is_string())
      throw std::runtime_error(error->get<std::string>());  // as the driver's own throw would reach the plugin
    return answer.value("result", nlohmann::json());
  }

 private:
  std::string op_;
  CallSender send_;
  std::shared_ptr<CallOutcome> outcome_;
};

// What every stand-in does: halt and status.
template <class Primary> class Remote : public Primary {
 public:
  explicit Remote(Caller caller) : caller_(std::move(caller)) {}
  void halt() noexcept override {
    try {
      caller_.call("halt", nlohmann::json::array());
    } catch (...) {  // rcand halts it regardless when this capability's process ends
    }
  }
  nlohmann::json status() const override { return caller_.call("status", nlohmann::json::array()); }

 protected:
  Caller caller_;
};

class RemoteDrive final : public Remote<sdk::DifferentialDrive> {
 public:
  using Remote::Remote;
  void set_wheel_speeds(double left, double right) override { caller_.call("set_wheel_speeds", {left, right}); }
};

class RemoteArm final : public Remote<sdk::ActuatorDriver>, public sdk::JointArm {
 public:
  using Remote::Remote;
  std::string_view interface_name() const noexcept override { return sdk::JointArm::kInterface; }
  void set_joint_targets(const std::vector<sdk::JointTarget>& targets) override {
    nlohmann::json args = nlohmann::json::array();
    for (const auto& t : targets) args.push_back({t.joint, t.position_deg, t.velocity_dps});
    caller_.call("set_joint_targets", std::move(args));
  }
  std::vector<sdk::JointState> joint_states() const override {
    std::vector<sdk::JointState> states;
    for (const auto& s : caller_.call("joint_states", nlohmann::json::array())) {
      sdk::JointState state{s.at(0).get<std::string>(), std::nullopt,        s.at(2).get<double>(),
                            s.at(3).get<double>(),      s.at(4).get<bool>(), s.at(5).get<bool>()};
      if (!s.at(1).is_null()) state.position_deg = s.at(1).get<double>();
      states.push_back(std::move(state));
    }
    return states;
  }
};

// [[joint, position_deg, velocity_dps], ...], checked whole before anything moves.
std::vector<sdk::JointTarget> joint_targets(const nlohmann::json& args) {
  if (!args.is_array()) throw CallError("set_joint_targets: the targets must be a list");
  std::vector<sdk::JointTarget> targets;
  for (const auto& target : args) {
    if (!target.is_array() || target.size() != 3 || !target[0].is_string())
      throw CallError("set_joint_targets: each target must be [joint, position_deg, velocity_dps]");
    targets.push_back(
        {target[0].get<std::string>(), number_at(target, 1, "set_joint_targets"), number_at(target, 2, "set_joint_targets")});
  }
  return targets;
}

}  // namespace

ActuatorCommand command_for(std::string_view method, const nlohmann::json& args) {
  if (method == "halt")
    return [](sdk::ActuatorDriver& actuator) {
      actuator.halt();
      return true;
    };
  if (method == "set_wheel_speeds") {
    const double left = number_at(args, 0, method), right = number_at(args, 1, method);
    return [left, right](sdk::ActuatorDriver& actuator) {
      auto* drive = dynamic_cast<sdk::DifferentialDrive*>(&actuator);
      if (drive != nullptr) drive->set_wheel_speeds(left, right);
      return drive != nullptr;
    };
  }
  if (method == "set_joint_targets")
    return [targets = joint_targets(args)](sdk::ActuatorDriver& actuator) {
      auto* arm = dynamic_cast<sdk::JointArm*>(&actuator);
      if (arm != nullptr) arm->set_joint_targets(targets);
      return arm != nullptr;
    };
  throw CallError("no actuator interface an isolated capability can call has a method '" + std::string(method) + "'");
}

ActuatorReading reading_for(std::string_view method) {
  if (method == "status")
    return [](const sdk::ActuatorDriver& actuator) { return std::optional<nlohmann::json>(actuator.status()); };
  if (method == "joint_states")
    return [](const sdk::ActuatorDriver& actuator) -> std::optional<nlohmann::json> {
      const auto* arm = dynamic_cast<const sdk::JointArm*>(&actuator);
      if (arm == nullptr) return std::nullopt;
      nlohmann::json states = nlohmann::json::array();
      for (const auto& s : arm->joint_states())
        states.push_back({s.joint, s.position_deg ? nlohmann::json(*s.position_deg) : nlohmann::json(), s.target_deg,
                          s.velocity_dps, s.moving, s.torque_on});
      return states;
    };
  throw CallError("no actuator interface an isolated capability can read has a reading '" + std::string(method) + "'");
}

std::unique_ptr<sdk::ActuatorDriver> remote_actuator(std::string_view interface, std::string_view op, CallSender send,
                                                     std::shared_ptr<CallOutcome> outcome) {
  if (interface == sdk::DifferentialDrive::kInterface)
    return std::make_unique<RemoteDrive>(Caller(op, std::move(send), std::move(outcome)));
  if (interface == sdk::JointArm::kInterface) return std::make_unique<RemoteArm>(Caller(op, std::move(send), std::move(outcome)));
  return nullptr;
}

}  // namespace rcand::isolation
