// Built for the kernel's own ABI minor: its stream routes are served.
#include "streams.hpp"

namespace {
void register_streams(rcand::sdk::Registrar& registrar) {
  registrar.add_capability({"org.rcand.test.stream_current", false},
                           [](rcand::sdk::PluginContext&) { return std::make_unique<rcand::test::StreamingCapability>(false); });
}
}  // namespace

RCAND_PLUGIN("org.rcand.test.stream_current", "1.0.0", register_streams)
