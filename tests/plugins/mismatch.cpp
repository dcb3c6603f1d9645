// Registers org.rcand.test.mismatch_extra (not in its manifest) and not org.rcand.test.mismatch_missing
// (in its manifest): manifest-mismatch.
#include "fixture.hpp"

namespace {
void register_mismatch(rcand::sdk::Registrar& registrar) {
  rcand::test::add_ping_capability(registrar, "org.rcand.test.mismatch");
  rcand::test::add_ping_capability(registrar, "org.rcand.test.mismatch_extra");
}
}  // namespace

RCAND_PLUGIN("org.rcand.test.mismatch", "1.0.0", register_mismatch)
