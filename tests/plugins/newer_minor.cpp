// Exports the right entry symbol, but its descriptor claims a minor ABI newer than the kernel's.
#include "fixture.hpp"

namespace {
void register_newer(rcand_registrar* registrar) {
  rcand::test::add_ping_capability(*reinterpret_cast<rcand::sdk::Registrar*>(registrar), "org.rcand.test.newer_minor");
}
}  // namespace

extern "C" RCAND_EXPORT const rcand_plugin_descriptor* RCAND_ENTRY_FUNCTION(void) {
  static const rcand_plugin_descriptor descriptor{
      sizeof(rcand_plugin_descriptor), RCAND_DESCRIPTOR_MAGIC, RCAND_ABI_MAJOR, RCAND_ABI_MINOR + 1,
      "org.rcand.test.newer_minor",    "1.0.0",                "fixture",       register_newer};
  return &descriptor;
}
