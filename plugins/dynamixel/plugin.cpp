// Registration: exactly what manifests/dynamixel.json provides. "dynamixel_v2" is the name other RCAN runtimes write.
#include <rcand/sdk/plugin.hpp>

#include "dynamixel_driver.hpp"
#include "posix_serial.hpp"

namespace {

using namespace rcand::plugins::dynamixel;

std::unique_ptr<rcand::sdk::Driver> make_dynamixel(rcand::sdk::PluginContext& ctx) {
  auto settings = DynamixelSettings::from(ctx.config(), ctx.robot_config());
  // A missing adapter is a named fault here ("cannot open /dev/ttyUSB0: ..."), never a silent mock.
  auto link = std::make_shared<PosixSerial>(settings.port, settings.baud_rate);
  return std::make_unique<DynamixelDriver>(std::move(settings), std::move(link), &ctx.log());
}

void register_dynamixel(rcand::sdk::Registrar& registrar) {
  // The arm is the primary use; a config with wheels makes an instance whose interface is differential_drive.
  for (const char* protocol : {"dynamixel", "dynamixel_v2"})
    registrar.add_driver({protocol, true, std::string(rcand::sdk::JointArm::kInterface)}, make_dynamixel);
}

}  // namespace

RCAND_PLUGIN("org.rcand.dynamixel", "0.1.0", register_dynamixel)
