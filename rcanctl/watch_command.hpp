// rcanctl watch: WS /ws/telemetry in the terminal, a table redrawn on every frame (one line per frame when the
// output is not a terminal), or each frame as a JSON line with --json.
#pragma once

#include <span>
#include <string>

namespace rcand::rcanctl {

int run_watch(std::span<const std::string> args);

}  // namespace rcand::rcanctl
