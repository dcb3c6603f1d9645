#include "arm.hpp"

#include <rcand/sdk/request_body.hpp>

#include <cmath>

namespace rcand::plugins::arm {

namespace {

using sdk::GateStatus;
using sdk::Json;
using sdk::Response;

constexpr std::size_t kMaxJointName = 64;

std::vector<JointLimit> read_limits(const sdk::PluginContext& ctx, const std::optional<std::string>& driver, std::string& where) {
  auto limits = joint_limits_from(ctx.robot_config(), driver, where);
  // Moving an arm without knowing its range is how it hits its own base: no limits, no arm.
  if (limits.empty())
    throw sdk::ConfigError(
        "arm: no joint limits: list the joints ({joint, min_deg, max_deg}) in physics.kinematics or in the arm driver's joints");
  return limits;
}

Response no_arm() {
  return Response::error(503, "UNAVAILABLE", "arm: no arm actuator is configured (a driver such as sim_arm, or set driver)");
}

Json limit_json(const JointLimit& j) {
  return {
      {"min_deg", j.min_deg}, {"max_deg", j.max_deg}, {"max_velocity_dps", j.max_velocity_dps}, {"max_step_deg", j.max_step_deg}};
}

}  // namespace

ArmCapability::ArmCapability(sdk::PluginContext& ctx)
    : ctx_(ctx),
      configured_driver_(ctx.config().get<std::string>("driver")),
      limits_(read_limits(ctx, configured_driver_, limits_from_)),
      poses_(read_poses()),
      gripper_joint_(ctx.config().get<std::string>("gripper_joint")) {
  if (gripper_joint_ && find_joint(limits_, *gripper_joint_) == nullptr)
    throw sdk::ConfigError("gripper_joint: '" + *gripper_joint_ + "' is not a joint in " + limits_from_);
}

// `poses`: {name: {joint: degrees}}. Each checked against the limits now, so a typo fails at startup, not mid-task.
std::map<std::string, ArmCapability::Pose> ArmCapability::read_poses() const {
  std::map<std::string, Pose> poses;
  const Json raw = ctx_.config().sub("poses").raw();  // a copy: sub() returns a temporary view
  if (raw.is_null() || (raw.is_object() && raw.empty())) return poses;
  if (!raw.is_object()) throw sdk::ConfigError("poses: expected a map of pose name to {joint: degrees}, found " + raw.dump());
  for (const auto& [name, joints] : raw.items()) {
    const std::string at = "poses." + name;
    if (!joints.is_object() || joints.empty())
      throw sdk::ConfigError(at + ": expected a non-empty map of joint name to degrees, found " + joints.dump());
    Pose pose;
    for (const auto& [joint, value] : joints.items()) {
      const JointLimit* limit = find_joint(limits_, joint);
      if (limit == nullptr) throw sdk::ConfigError(at + "." + joint + ": no joint '" + joint + "' in " + limits_from_);
      if (!value.is_number() || !std::isfinite(value.get<double>()))
        throw sdk::ConfigError(at + "." + joint + ": expected a number of degrees, found " + value.dump());
      const double deg = value.get<double>();
      if (deg < limit->min_deg || deg > limit->max_deg)
        throw sdk::ConfigError(at + "." + joint + ": " + shortest(deg) + " is outside the joint's range [" +
                               shortest(limit->min_deg) + ", " + shortest(limit->max_deg) + "]");
      pose.emplace_back(joint, deg);
    }
    poses.emplace(name, std::move(pose));
  }
  return poses;
}

std::vector<sdk::Route> ArmCapability::routes() {
  return {
      {"POST", "/api/action", sdk::Scope::Control, true, "arm_pose", [this](const sdk::Request& r) { return arm_pose(r); }},
      {"POST", "/api/action", sdk::Scope::Control, true, "grip", [this](const sdk::Request& r) { return grip(r); }},
      {"GET", "/api/arm/joints", sdk::Scope::Status, false, "", [this](const sdk::Request& r) { return joints(r); }},
  };
}

std::optional<std::string> ArmCapability::resolve_arm() const {
  if (configured_driver_) return configured_driver_;
  auto& gate = ctx_.motion();
  if (auto id = gate.first_actuator(sdk::JointArm::kInterface)) return id;
  for (const auto& info : gate.actuators())  // an arm offered by a driver with another primary interface
    if (gate.inspect_as<sdk::JointArm>(info.id, [](const sdk::JointArm&) {}) == GateStatus::Ok) return info.id;
  return std::nullopt;
}

Response ArmCapability::arm_pose(const sdk::Request& request) {
  const Json& body = request.body;
  if (!body.is_object()) return Response::bad_request("body", "the body must be a JSON object");
  const bool has_pose = body.contains("pose") && !body["pose"].is_null();
  const bool has_joints = body.contains("joints") && !body["joints"].is_null();
  if (has_pose == has_joints)
    return Response::bad_request(has_pose ? "joints" : "pose",
                                 "give exactly one of joints ({\"joint\": degrees, ...}) or pose (a named pose)");
  MoveRequest move_request;
  Json answer{{"ok", true}, {"type", "arm_pose"}, {"pose", nullptr}};
  if (has_pose) {
    const Json& name = body["pose"];
    Json allowed = Json::array();
    for (const auto& [known, pose] : poses_) allowed.push_back(known);
    const auto it = name.is_string() ? poses_.find(name.get<std::string>()) : poses_.end();
    if (it == poses_.end())
      return Response::error(400, "BAD_REQUEST",
                             "unknown pose " + sdk::describe_value(name) + " (configured in runtime.capabilities.arm.poses)",
                             Json{{"field", "pose"}, {"allowed", allowed}});
    move_request.targets = it->second;
    move_request.field = "pose." + it->first;
    answer["pose"] = it->first;
  } else {
    const Json& joints = body["joints"];
    if (!joints.is_object() || joints.empty())
      return Response::bad_request(
          "joints", "joints must be a non-empty object of joint name to degrees, found " + sdk::describe_value(joints));
    for (const auto& [joint, value] : joints.items()) {
      if (joint.size() > kMaxJointName)  // every later message names the joint: never a client's megabyte
        return Response::bad_request("joints", "a joint name is at most " + std::to_string(kMaxJointName) + " bytes, found " +
                                                   std::to_string(joint.size()));
      if (!value.is_number())
        return Response::bad_request("joints." + joint, "joint '" + joint + "' target must be a number of degrees, found " +
                                                            std::string(value.type_name()));
      move_request.targets.emplace_back(joint, value.get<double>());
    }
  }
  if (body.contains("velocity_dps") && !body["velocity_dps"].is_null()) {
    if (!body["velocity_dps"].is_number())
      return Response::bad_request("velocity_dps",
                                   "velocity_dps must be a number > 0, found " + sdk::describe_value(body["velocity_dps"]));
    move_request.velocity_dps = body["velocity_dps"].get<double>();
  }
  return move(move_request, std::move(answer));
}

Response ArmCapability::grip(const sdk::Request& request) {
  const Json& body = request.body;
  if (!body.is_object()) return Response::bad_request("body", "the body must be a JSON object");
  const auto found = body.find("state");
  const Json state = found != body.end() ? *found : Json();
  if (!state.is_string() || (state != "open" && state != "close"))
    return Response::error(400, "BAD_REQUEST", "state must be \"open\" or \"close\", found " + sdk::describe_value(state),
                           {{"field", "state"}, {"allowed", {"open", "close"}}});
  if (!gripper_joint_)
    return Response::error(400, "BAD_REQUEST", "this arm has no gripper: set runtime.capabilities.arm.gripper_joint",
                           {{"field", "type"}});
  const JointLimit& joint = *find_joint(limits_, *gripper_joint_);
  MoveRequest move_request;
  move_request.targets.emplace_back(joint.joint, state == "open" ? joint.max_deg : joint.min_deg);
  move_request.cap_step = false;  // open and close are the two ends of the range, by definition
  move_request.field = "state";
  return move(move_request, {{"ok", true}, {"type", "grip"}, {"state", state}});
}

Response ArmCapability::move(const MoveRequest& move_request, Json answer) {
  const auto driver = resolve_arm();
  if (!driver) return no_arm();
  // Steps are measured from where the arm is: read it through the gate (never refused; reading moves nothing).
  std::vector<sdk::JointState> present;
  GateStatus gate =
      ctx_.motion().inspect_as<sdk::JointArm>(*driver, [&](const sdk::JointArm& arm) { present = arm.joint_states(); });
  if (gate != GateStatus::Ok) return sdk::gate_refusal(gate, *driver);

  auto plan = plan_move(move_request, limits_, present, limits_from_);
  if (auto* refusal = std::get_if<Response>(&plan)) return *refusal;
  const auto& targets = std::get<std::vector<sdk::JointTarget>>(plan);

  gate = ctx_.motion().actuate_as<sdk::JointArm>(*driver, [&](sdk::JointArm& arm) { arm.set_joint_targets(targets); });
  if (gate != GateStatus::Ok) return sdk::gate_refusal(gate, *driver);

  Json sent = Json::object(), speeds = Json::object();
  for (const auto& t : targets) {
    sent[t.joint] = t.position_deg;
    speeds[t.joint] = t.velocity_dps;
  }
  answer["driver"] = *driver;
  answer["targets"] = sent;
  answer["velocity_dps"] = speeds;
  answer["eta_ms"] = eta_ms(targets, present);
  remember(answer);
  return Response::ok(std::move(answer));
}

Response ArmCapability::joints(const sdk::Request&) {
  const auto driver = resolve_arm();
  if (!driver) return no_arm();
  std::vector<sdk::JointState> present;
  const GateStatus gate =
      ctx_.motion().inspect_as<sdk::JointArm>(*driver, [&](const sdk::JointArm& arm) { present = arm.joint_states(); });
  if (gate != GateStatus::Ok) return sdk::gate_refusal(gate, *driver);
  Json joints = Json::array();
  for (const auto& s : present) {
    Json j{{"joint", s.joint},           {"position_deg", s.position_deg ? Json(*s.position_deg) : Json(nullptr)},
           {"target_deg", s.target_deg}, {"velocity_dps", s.velocity_dps},
           {"moving", s.moving},         {"torque_on", s.torque_on}};
    if (const JointLimit* limit = find_joint(limits_, s.joint)) j["limits"] = limit_json(*limit);
    joints.push_back(std::move(j));
  }
  Json poses = Json::object();
  for (const auto& [name, pose] : poses_) {
    Json p = Json::object();
    for (const auto& [joint, deg] : pose) p[joint] = deg;
    poses[name] = std::move(p);
  }
  return Response::ok({{"driver", *driver},
                       {"joints", std::move(joints)},
                       {"poses", std::move(poses)},
                       {"gripper_joint", gripper_joint_ ? Json(*gripper_joint_) : Json(nullptr)},
                       {"limits_from", limits_from_}});
}

void ArmCapability::remember(Json command) {
  {
    std::lock_guard lock(mutex_);
    command["t_ms"] = ctx_.clock().wall_ms();
    last_command_ = std::move(command);
    ++commands_;
  }
  publish();
}

void ArmCapability::publish() noexcept {
  try {
    ctx_.publish_status(status());
  } catch (...) {  // no memory for the status: the kernel asks status() itself a second later
  }
}

// The gate has already halted the driver, which holds the pose with torque on: nothing here may drop it.
void ArmCapability::on_estop() noexcept {
  {
    std::lock_guard lock(mutex_);
    ++estops_;
  }
  publish();
}

Json ArmCapability::status() const {
  Json joints = Json::array();
  for (const auto& j : limits_) joints.push_back(j.joint);
  Json poses = Json::array();
  for (const auto& [name, pose] : poses_) poses.push_back(name);
  std::lock_guard lock(mutex_);
  return {{"joints", std::move(joints)},  {"limits_from", limits_from_},
          {"poses", std::move(poses)},    {"gripper_joint", gripper_joint_ ? Json(*gripper_joint_) : Json(nullptr)},
          {"commands", commands_},        {"estops", estops_},
          {"last_command", last_command_}};
}

}  // namespace rcand::plugins::arm
