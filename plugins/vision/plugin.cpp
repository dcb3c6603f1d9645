// Registration: exactly what manifests/vision.json provides.
#include "vision.hpp"

namespace {

void register_vision(rcand::sdk::Registrar& registrar) {
  registrar.add_capability({"vision", false},
                           [](rcand::sdk::PluginContext& ctx) { return std::make_unique<rcand::plugins::vision::Vision>(ctx); });
}

}  // namespace

RCAND_PLUGIN("org.rcand.vision", "0.1.0", register_vision)
