// `rcanctl fleet keygen|enroll|revoke|list|stop` (docs/protocol.md §11, README "A fleet of ten robots"): a robot's
// Ed25519 key pair, the fleet's peers file every robot reads (runtime.r2r.peers_file), and the fleet e-stop: one
// signed R2R `command` {"type":"estop"} published on the broker's r2r/broadcast.
#pragma once

#include <iosfwd>
#include <span>
#include <string>

namespace rcand::rcanctl {

int run_fleet(std::span<const std::string> args);
int run_fleet(std::span<const std::string> args, std::ostream& out, std::ostream& err);

}  // namespace rcand::rcanctl
