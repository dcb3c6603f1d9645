// The operator's daily work on one robot: the e-stop, teleop moves (with hold-to-move), nav jobs, the plugins and
// the audit log. Each takes the connection options of robot_connection.hpp; exit codes as exit_codes.hpp.
#pragma once

#include <span>
#include <string>

namespace rcand::rcanctl {

int run_estop(std::span<const std::string> args);    // estop [show] | estop clear
int run_move(std::span<const std::string> args);     // move --linear X --angular Y [--duration MS | --hold]
int run_nav(std::span<const std::string> args);      // nav go --distance M [--heading D] [--speed S] | status | cancel
int run_plugins(std::span<const std::string> args);  // plugins
int run_audit(std::span<const std::string> args);    // audit [--limit N] [--follow]

}  // namespace rcand::rcanctl
