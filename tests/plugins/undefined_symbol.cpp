// Built with ALLOW_UNDEFINED and calls a function nothing defines: dlopen with RTLD_NOW fails.
#include "fixture.hpp"

extern "C" void rcand_test_symbol_nobody_defines();

namespace {
void register_undefined(rcand::sdk::Registrar& registrar) {
  rcand_test_symbol_nobody_defines();
  rcand::test::add_ping_capability(registrar, "org.rcand.test.undefined_symbol");
}
}  // namespace

RCAND_PLUGIN("org.rcand.test.undefined_symbol", "1.0.0", register_undefined)
