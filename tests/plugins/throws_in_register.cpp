// Its register function throws: registration-failed, and the kernel keeps going.
#include <stdexcept>

#include "fixture.hpp"

namespace {
void register_throws(rcand::sdk::Registrar&) { throw std::runtime_error("register exploded on purpose"); }
}  // namespace

RCAND_PLUGIN("org.rcand.test.throws_in_register", "1.0.0", register_throws)
