// Built as a plugin for ABI 1.0 would have been: its descriptor says minor 0, and it never calls what 1.1 added
// (PluginContext::publish_status). A kernel of a newer minor must still load it and serve its routes.
#include "../fixture.hpp"

namespace {
void register_older(rcand_registrar* registrar) {
  rcand::test::add_ping_capability(*reinterpret_cast<rcand::sdk::Registrar*>(registrar), "org.rcand.test.older_minor");
}
}  // namespace

extern "C" RCAND_EXPORT const rcand_plugin_descriptor* RCAND_ENTRY_FUNCTION(void) {
  static const rcand_plugin_descriptor descriptor{sizeof(rcand_plugin_descriptor),
                                                  RCAND_DESCRIPTOR_MAGIC,
                                                  RCAND_ABI_MAJOR,
                                                  0,
                                                  "org.rcand.test.older_minor",
                                                  "1.0.0",
                                                  "fixture",
                                                  register_older};
  return &descriptor;
}
