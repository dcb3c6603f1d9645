// Registration: exactly what manifests/gpio.json provides.
#include <rcand/sdk/plugin.hpp>

#include "gpio_motor_drive.hpp"
#include "libgpiod_chip.hpp"
#include "sysfs_pwm.hpp"

namespace {

using namespace rcand::plugins::gpio_motor;

std::unique_ptr<rcand::sdk::Driver> make_gpio_drive(rcand::sdk::PluginContext& ctx) {
  auto settings = GpioMotorSettings::from(ctx.config());
  // A missing chip is a named fault here, never a silent mock.
  std::shared_ptr<GpioChip> chip = LibgpiodChip::open(settings.chip, settings.first_line_name());
  PwmFactory pwm = [root = settings.sysfs_root](const PwmSettings& p) {
    return std::make_unique<SysfsPwm>(p.chip, p.channel, p.frequency_hz, root);
  };
  return std::make_unique<GpioMotorDrive>(std::move(settings), std::move(chip), std::move(pwm), &ctx.log());
}

void register_gpio(rcand::sdk::Registrar& registrar) {
  registrar.add_driver({"gpio", true, std::string(rcand::sdk::DifferentialDrive::kInterface)}, make_gpio_drive);
}

}  // namespace

RCAND_PLUGIN("org.rcand.gpio_motor", "0.1.0", register_gpio)
