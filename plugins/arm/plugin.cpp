// Registration: exactly what manifests/arm.json provides.
#include <rcand/sdk/plugin.hpp>

#include "arm.hpp"
#include "sim_arm.hpp"

namespace {

using rcand::plugins::arm::ArmCapability;
using rcand::plugins::arm::joint_limits_from;
using rcand::plugins::arm::parse_joint_limits;
using rcand::plugins::arm::SimArm;

// The driver's own joints[] first, then the joints of physics.kinematics.
std::unique_ptr<rcand::sdk::Driver> make_sim_arm(rcand::sdk::PluginContext& ctx) {
  std::string where = "joints";
  auto joints = ctx.config().has("joints") ? parse_joint_limits(ctx.config().sub("joints").raw(), where)
                                           : joint_limits_from(ctx.robot_config(), std::nullopt, where);
  if (joints.empty())
    throw rcand::sdk::ConfigError(
        "sim_arm: no joints: give joints[] ({joint, min_deg, max_deg}) or joints in physics.kinematics");
  auto arm = std::make_unique<SimArm>(ctx.clock(), std::move(joints), &ctx);
  ctx.log().info("sim arm '", ctx.instance_id(), "': ", arm->joints().size(), " joints from ", where);
  return arm;
}

void register_arm(rcand::sdk::Registrar& registrar) {
  registrar.add_capability({"arm", true}, [](rcand::sdk::PluginContext& ctx) { return std::make_unique<ArmCapability>(ctx); });
  registrar.add_driver({"sim_arm", true, std::string(rcand::sdk::JointArm::kInterface)}, make_sim_arm);
}

}  // namespace

RCAND_PLUGIN("org.rcand.arm", "0.1.0", register_arm)
