#include "libs/isolation/actuator_calls.hpp"

#include <utility>

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

class RemoteDrive final : public sdk::DifferentialDrive {
 public:
  explicit RemoteDrive(Caller caller) : caller_(std::move(caller)) {}
  void set_wheel_speeds(double left, double right) override { caller_.call("set_wheel_speeds", {left, right}); }
  void halt() noexcept override {
    try {
      caller_.call("halt", nlohmann::json::array());
    } catch (...) {  // rcand halts it regardless when this capability's process ends
    }
  }
  nlohmann::json status() const override { return caller_.call("status", nlohmann::json::array()); }

 private:
  Caller caller_;
};

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
  throw CallError("no actuator interface an isolated capability can call has a method '" + std::string(method) + "'");
}

ActuatorReading reading_for(std::string_view method) {
  if (method == "status") return [](const sdk::ActuatorDriver& actuator) { return actuator.status(); };
  throw CallError("no actuator interface an isolated capability can read has a reading '" + std::string(method) + "'");
}

std::unique_ptr<sdk::ActuatorDriver> remote_actuator(std::string_view interface, std::string_view op, CallSender send,
                                                     std::shared_ptr<CallOutcome> outcome) {
  if (interface == sdk::DifferentialDrive::kInterface)
    return std::make_unique<RemoteDrive>(Caller(op, std::move(send), std::move(outcome)));
  return nullptr;
}

}  // namespace rcand::isolation
