// `rcanctl r2r send|watch|auction` (docs/protocol.md §11): talk R2R to a robot over its WS /ws/r2r (or watch a fleet's MQTT
// broker), and run auctions through POST /api/r2r/auction.
#pragma once

#include <iosfwd>
#include <span>
#include <string>

namespace rcand::rcanctl {

int run_r2r(std::span<const std::string> args);
int run_r2r(std::span<const std::string> args, std::ostream& out, std::ostream& err);

}  // namespace rcand::rcanctl
