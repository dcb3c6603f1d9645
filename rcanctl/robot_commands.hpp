// `rcanctl status`, `rcanctl stop`, `rcanctl command --instruction "…"`: one robot (--host/--port/--token, or
// --node NAME from --swarm FILE).
#pragma once

#include <iosfwd>
#include <span>
#include <string>

namespace rcand::rcanctl {

int run_status(std::span<const std::string> args);
int run_stop(std::span<const std::string> args);
int run_command(std::span<const std::string> args);
// The same with explicit streams (tests).
int run_robot(std::string_view operation, std::span<const std::string> args, std::ostream& out, std::ostream& err);

}  // namespace rcand::rcanctl
