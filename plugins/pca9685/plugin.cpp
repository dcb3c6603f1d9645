// Registration: exactly what manifests/pca9685.json provides. "pca9685_i2c" is the name other RCAN runtimes write.
#include <rcand/sdk/plugin.hpp>

#include "gpio_line.hpp"
#include "linux_i2c_bus.hpp"
#include "pca9685_drive.hpp"

namespace {

using namespace rcand::plugins::pca9685;

std::unique_ptr<rcand::sdk::Driver> make_pca9685(rcand::sdk::PluginContext& ctx) {
  auto settings = Pca9685Settings::from(ctx.config());
  auto bus = std::make_shared<LinuxI2cBus>(settings.bus_path, settings.i2c_timeout);
  std::unique_ptr<OutputPin> oe;
  // Requested high (outputs disabled) until start() has put the chip in a known state.
  if (settings.oe_line) oe = std::make_unique<GpioLine>(*settings.oe_chip, *settings.oe_line, true);
  if (!oe)
    ctx.log().warn("pca9685 '", ctx.instance_id(), "': no /OE pin (oe_line): if rcand dies, the outputs keep their last value");
  return std::make_unique<Pca9685Drive>(std::move(settings), std::move(bus), std::move(oe), &ctx.log());
}

void register_pca9685(rcand::sdk::Registrar& registrar) {
  for (const char* protocol : {"pca9685", "pca9685_i2c"})
    registrar.add_driver({protocol, true, std::string(rcand::sdk::DifferentialDrive::kInterface)}, make_pca9685);
}

}  // namespace

RCAND_PLUGIN("org.rcand.pca9685", "0.1.0", register_pca9685)
