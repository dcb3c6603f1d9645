// Fault drill fixture: its register function never returns. The plugin host gives up on it after the register
// timeout (registration-failed) and the robot starts without it.
#include <chrono>
#include <thread>

#include "../fixture.hpp"

namespace {
void register_hangs(rcand::sdk::Registrar&) {
  for (;;) std::this_thread::sleep_for(std::chrono::hours(1));
}
}  // namespace

RCAND_PLUGIN("org.rcand.test.hangs_in_register", "1.0.0", register_hangs)
