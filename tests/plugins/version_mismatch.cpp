// Its descriptor says version 2.0.0 while its manifest says 1.0.0: manifest-mismatch.
#include "fixture.hpp"

namespace {
void register_version(rcand::sdk::Registrar& registrar) {
  rcand::test::add_ping_capability(registrar, "org.rcand.test.version_mismatch");
}
}  // namespace

RCAND_PLUGIN("org.rcand.test.version_mismatch", "2.0.0", register_version)
