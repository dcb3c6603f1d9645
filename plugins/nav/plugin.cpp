// Registration: exactly what manifests/nav.json provides.
#include "nav.hpp"

namespace {

void register_nav(rcand::sdk::Registrar& registrar) {
  registrar.add_capability({"nav", true}, [](rcand::sdk::PluginContext& ctx) {
    return std::make_unique<rcand::plugins::nav::Nav>(ctx);
  });
}

}  // namespace

RCAND_PLUGIN("org.rcand.nav", "0.1.0", register_nav)
