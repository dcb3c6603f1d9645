// Registration: exactly what manifests/teleop.json provides.
#include "teleop.hpp"

namespace {

void register_teleop(rcand::sdk::Registrar& registrar) {
  registrar.add_capability({"teleop", true}, [](rcand::sdk::PluginContext& ctx) {
    return std::make_unique<rcand::plugins::teleop::Teleop>(ctx);
  });
}

}  // namespace

RCAND_PLUGIN("org.rcand.teleop", "0.1.0", register_teleop)
