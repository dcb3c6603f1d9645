// Declares ABI minor 1, so the kernel must not call stream_routes() (which throws here to show it was called).
#include "streams.hpp"

namespace {
void register_streams(rcand_registrar* registrar) {
  reinterpret_cast<rcand::sdk::Registrar*>(registrar)->add_capability(
      {"org.rcand.test.stream_minor_one", false},
      [](rcand::sdk::PluginContext&) { return std::make_unique<rcand::test::StreamingCapability>(true); });
}
}  // namespace

extern "C" RCAND_EXPORT const rcand_plugin_descriptor* RCAND_ENTRY_FUNCTION(void) {
  static_assert(RCAND_ABI_MINOR >= 2, "stream routes came with ABI 1.2");
  static const rcand_plugin_descriptor descriptor{sizeof(rcand_plugin_descriptor),
                                                  RCAND_DESCRIPTOR_MAGIC,
                                                  RCAND_ABI_MAJOR,
                                                  1,
                                                  "org.rcand.test.stream_minor_one",
                                                  "1.0.0",
                                                  "fixture",
                                                  register_streams};
  return &descriptor;
}
