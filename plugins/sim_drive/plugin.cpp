// Registration: exactly what manifests/sim_drive.json provides.
#include <rcand/sdk/plugin.hpp>

#include "sim_drive.hpp"

namespace {

void register_sim_drive(rcand::sdk::Registrar& registrar) {
  using rcand::plugins::sim_drive::SimDrive;
  using rcand::plugins::sim_drive::SimDriveSettings;
  registrar.add_driver({"sim_diff_drive", true, std::string(rcand::sdk::DifferentialDrive::kInterface)},
                       [](rcand::sdk::PluginContext& ctx) -> std::unique_ptr<rcand::sdk::Driver> {
                         auto drive = std::make_unique<SimDrive>(ctx.clock(), SimDriveSettings::from(ctx), &ctx);
                         const auto& s = drive->settings();
                         ctx.log().info("sim drive '", ctx.instance_id(), "': ", s.max_wheel_rps, " rps, ",
                                        s.wheel_circumference_m, " m circumference, ", s.wheel_base_m, " m base");
                         return drive;
                       });
}

}  // namespace

RCAND_PLUGIN("org.rcand.sim_drive", "0.1.0", register_sim_drive)
