// Registration: exactly what manifests/fleet.json provides.
#include "fleet.hpp"

namespace {

void register_fleet(rcand::sdk::Registrar& registrar) {
  registrar.add_capability({"org.rcand.fleet", false},
                           [](rcand::sdk::PluginContext& ctx) { return std::make_unique<rcand::plugins::fleet::Fleet>(ctx); });
}

}  // namespace

RCAND_PLUGIN("org.rcand.fleet", "0.1.0", register_fleet)
