// Registration: exactly what manifests/feetech.json provides.
#include <rcand/sdk/plugin.hpp>

#include "dynamixel/posix_serial.hpp"
#include "feetech_driver.hpp"

namespace {

using namespace rcand::plugins::feetech;

std::unique_ptr<rcand::sdk::Driver> make_feetech(rcand::sdk::PluginContext& ctx) {
  auto settings = FeetechSettings::from(ctx.config(), ctx.robot_config());
  // A missing adapter is a named fault here ("cannot open /dev/ttyACM0: ..."), never a silent mock.
  auto link = std::make_shared<rcand::plugins::dynamixel::PosixSerial>(settings.port, settings.baud_rate);
  return std::make_unique<FeetechDriver>(std::move(settings), std::move(link), &ctx.log());
}

void register_feetech(rcand::sdk::Registrar& registrar) {
  // The arm is the primary use; a config with wheels makes an instance whose interface is differential_drive.
  registrar.add_driver({"feetech", true, std::string(rcand::sdk::JointArm::kInterface)}, make_feetech);
}

}  // namespace

RCAND_PLUGIN("org.rcand.feetech", "0.1.0", register_feetech)
