// Registration: exactly what manifests/arduino.json provides.
#include <rcand/sdk/plugin.hpp>

#include "arduino_driver.hpp"

namespace {

using namespace rcand::plugins::arduino;

std::unique_ptr<rcand::sdk::Driver> make_arduino(rcand::sdk::PluginContext& ctx) {
  auto settings = ArduinoSettings::from(ctx.config());
  // A missing board is a named fault here ("cannot open /dev/ttyACM0: ..."), never a silent mock.
  auto bus = std::make_shared<ArduinoBus>(settings.port, settings.baud);
  return std::make_unique<ArduinoDriver>(std::move(settings), std::move(bus), &ctx.log(), &ctx);
}

void register_arduino(rcand::sdk::Registrar& registrar) {
  registrar.add_driver({"arduino_serial_json", true, std::string(rcand::sdk::DifferentialDrive::kInterface)}, make_arduino);
}

}  // namespace

RCAND_PLUGIN("org.rcand.arduino", "0.1.0", register_arduino)
