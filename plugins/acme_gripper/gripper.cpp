// com.acme.gripper: the simulated gripper driver, the capability, and the registration.
#include <rcand/sdk/bounded_text.hpp>  // quotes the caller's value back: cut to 200 bytes, no controls

#include <algorithm>
#include <cmath>

#include <rcand/sdk/request_body.hpp>

#include "gripper_capability.hpp"
#include "sim_gripper.hpp"

namespace acme::gripper {

using rcand::sdk::GateStatus;
using rcand::sdk::Json;
using rcand::sdk::Response;

// ---- SimGripper ----------------------------------------------------------------------------------------------

SimGripper::SimGripper(double object_size) : object_size_(object_size) {}

void SimGripper::set_opening(double opening) {
  std::lock_guard lock(mutex_);
  ++commands_;
  holding_ = object_size_ > 0.0 && opening < object_size_;
  opening_ = holding_ ? object_size_ : opening;
}
double SimGripper::opening() const {
  std::lock_guard lock(mutex_);
  return opening_;
}
bool SimGripper::holding() const {
  std::lock_guard lock(mutex_);
  return holding_;
}
void SimGripper::halt() noexcept {
  std::lock_guard lock(mutex_);
  ++halts_;
}
nlohmann::json SimGripper::status() const {
  std::lock_guard lock(mutex_);
  return {{"opening", opening_}, {"holding", holding_}, {"commands", commands_}, {"halts", halts_}};
}

// ---- GripperCapability ---------------------------------------------------------------------------------------

GripperCapability::GripperCapability(rcand::sdk::PluginContext& ctx)
    : ctx_(ctx), configured_driver_(ctx.config().get<std::string>("driver")) {}

std::vector<rcand::sdk::Route> GripperCapability::routes() {
  using rcand::sdk::Scope;
  return {
      {"GET", "/state", Scope::Control, false, "", [this](const rcand::sdk::Request& r) { return state(r); }},
      {"POST", "/grip", Scope::Control, true, "", [this](const rcand::sdk::Request& r) { return grip(r); }},
  };
}

std::optional<std::string> GripperCapability::resolve_actuator() const {
  if (configured_driver_) return configured_driver_;
  return ctx_.motion().first_actuator(Gripper::kInterface);
}

bool GripperCapability::remember(const Gripper& gripper) {
  const double opening = gripper.opening();
  const bool holding = gripper.holding();
  std::lock_guard lock(mutex_);
  const bool changed = opening_ != opening || holding_ != holding;
  opening_ = opening;
  holding_ = holding;
  return changed;
}

// Handlers run one at a time on the capability's worker, so publishes land in the order of the changes.
void GripperCapability::publish() noexcept {
  try {
    ctx_.publish_status(status());
  } catch (...) {  // no memory for the status: the kernel asks status() itself a second later
  }
}

Json GripperCapability::describe(const std::string& actuator) const {
  std::lock_guard lock(mutex_);
  return {{"opening", opening_ ? Json(*opening_) : Json(nullptr)}, {"holding", holding_}, {"actuator", actuator}};
}

Response GripperCapability::state(const rcand::sdk::Request&) {
  const auto actuator = resolve_actuator();
  if (!actuator) return Response::error(503, "UNAVAILABLE", "no com.acme.gripper actuator is configured");
  // Reading goes through the gate too (we never hold a driver); inspect() is never refused by the e-stop.
  bool changed = false;
  const GateStatus gate = ctx_.motion().inspect_as<Gripper>(*actuator, [&](const Gripper& g) { changed = remember(g); });
  if (gate != GateStatus::Ok) return rcand::sdk::gate_refusal(gate, *actuator);
  if (changed) publish();
  return Response::ok(describe(*actuator));
}

Response GripperCapability::grip(const rcand::sdk::Request& request) {
  const Json& body = request.body;
  if (!body.is_object()) return Response::bad_request("body", "the body must be a JSON object");
  const bool has_state = body.contains("state") && !body["state"].is_null();
  const bool has_opening = body.contains("opening") && !body["opening"].is_null();
  if (has_state == has_opening)
    return Response::bad_request(has_state ? "opening" : "state",
                                 "give exactly one of state (\"open\" or \"close\") or opening (a number in [0, 1])");
  double target = 0.0;
  if (has_state) {
    const Json& s = body["state"];
    if (!s.is_string() || (s != "open" && s != "close"))
      return Response::error(400, "BAD_REQUEST",
                             "state must be \"open\" or \"close\", found " + rcand::sdk::bounded_text(s.dump()),
                             {{"field", "state"}, {"allowed", {"open", "close"}}});
    target = s == "open" ? 1.0 : 0.0;
  } else {
    const Json& o = body["opening"];
    if (!o.is_number() || !std::isfinite(o.get<double>()) || o.get<double>() < 0.0 || o.get<double>() > 1.0)
      return Response::bad_request("opening", "opening must be a number in [0, 1], found " + rcand::sdk::bounded_text(o.dump()));
    target = o.get<double>();
  }

  const auto actuator = resolve_actuator();
  if (!actuator) return Response::error(503, "UNAVAILABLE", "no com.acme.gripper actuator is configured");
  bool changed = false;
  const GateStatus gate = ctx_.motion().actuate_as<Gripper>(*actuator, [&](Gripper& g) {
    g.set_opening(target);
    changed = remember(g);
  });
  if (changed) publish();  // also when the gate then refused: the opening did change
  if (gate != GateStatus::Ok) return rcand::sdk::gate_refusal(gate, *actuator);
  Json answer = describe(*actuator);
  answer["ok"] = true;
  return Response::ok(std::move(answer));
}

Json GripperCapability::status() const {
  std::lock_guard lock(mutex_);
  return {{"opening", opening_ ? Json(*opening_) : Json(nullptr)}, {"holding", holding_}};
}

}  // namespace acme::gripper

// ---- registration: exactly what com.acme.gripper.json provides ----------------------------------------------

namespace {

void register_gripper(rcand::sdk::Registrar& registrar) {
  registrar.add_capability({"com.acme.gripper", true}, [](rcand::sdk::PluginContext& ctx) {
    return std::make_unique<acme::gripper::GripperCapability>(ctx);
  });
  registrar.add_driver(
      {"acme_gripper_sim", true, std::string(acme::gripper::Gripper::kInterface)},
      [](rcand::sdk::PluginContext& ctx) -> std::unique_ptr<rcand::sdk::Driver> {
        const double object_size = ctx.config().get_or("object_size", 0.0);
        if (!std::isfinite(object_size) || object_size < 0.0 || object_size > 1.0)
          throw rcand::sdk::ConfigError("object_size: expected a number in [0, 1], found " + std::to_string(object_size));
        return std::make_unique<acme::gripper::SimGripper>(object_size);
      });
}

}  // namespace

RCAND_PLUGIN("com.acme.gripper", "1.0.0", register_gripper)
