// Same id as good.json; its manifest sorts after good's, so the kernel records it duplicate-id.
#include "fixture.hpp"

namespace {
void register_duplicate(rcand::sdk::Registrar& registrar) { rcand::test::add_ping_capability(registrar, "org.rcand.test.good"); }
}  // namespace

RCAND_PLUGIN("org.rcand.test.good", "9.9.9", register_duplicate)
