// Built "for ABI 2": exports only rcand_plugin_entry_v2, with a hand-written descriptor saying abi_major 2.
#include "fixture.hpp"

namespace {
void register_abi(rcand_registrar* registrar) {
  rcand::test::add_ping_capability(*reinterpret_cast<rcand::sdk::Registrar*>(registrar), "org.rcand.test.abi_major");
}
}  // namespace

extern "C" RCAND_EXPORT const rcand_plugin_descriptor* rcand_plugin_entry_v2(void) {
  static const rcand_plugin_descriptor descriptor{
      sizeof(rcand_plugin_descriptor), RCAND_DESCRIPTOR_MAGIC, 2, 0, "org.rcand.test.abi_major", "1.0.0", "fixture",
      register_abi};
  return &descriptor;
}
