// Registration: exactly what manifests/chat.json provides.
#include "chat.hpp"

namespace {

void register_chat(rcand::sdk::Registrar& registrar) {
  registrar.add_capability({"chat", false},
                           [](rcand::sdk::PluginContext& ctx) { return std::make_unique<rcand::plugins::chat::Chat>(ctx); });
}

}  // namespace

RCAND_PLUGIN("org.rcand.chat", "0.1.0", register_chat)
