// Needed for its own capability, but also registers org.rcand.test.good, which the good plugin (earlier in
// scan order) already registered: registration-failed.
#include "fixture.hpp"

namespace {
void register_clash(rcand::sdk::Registrar& registrar) {
  rcand::test::add_ping_capability(registrar, "org.rcand.test.good_name_clash");
  rcand::test::add_ping_capability(registrar, "org.rcand.test.good");
}
}  // namespace

RCAND_PLUGIN("org.rcand.test.good_name_clash", "1.0.0", register_clash)
