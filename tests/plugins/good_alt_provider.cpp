// A second provider of org.rcand.test.good: good.json is first in scan order, so this one is never opened.
#include "fixture.hpp"

namespace {
void register_alt(rcand::sdk::Registrar& registrar) { rcand::test::add_ping_capability(registrar, "org.rcand.test.good"); }
}  // namespace

RCAND_PLUGIN("org.rcand.test.good_alt_provider", "1.0.0", register_alt)
