#include "robot_commands.hpp"

#include <iostream>

#include "command_line.hpp"
#include "fleet_operation.hpp"

namespace rcand::rcanctl {
int run_robot(std::string_view operation, std::span<const std::string> args, std::ostream& out, std::ostream& err) {
  const Operation op = operation_named(operation);
  constexpr std::string_view kWhat[] = {
      "One robot's status: state, e-stop, capabilities; each driver or capability that is not ok, why, and the fix.",
      "Latch one robot's e-stop and confirm its motors stopped.",
      "Send one robot an instruction in words; prints what it understood and what it did."};
  FleetOptions options;
  const auto app = make_command_app(
      "rcanctl " + std::string(operation), kWhat[static_cast<int>(op)],
      "--node NAME [--swarm FILE] instead of --host/--port/--token: a node of swarm.yaml (address, token, TLS).\n"
      "Output: a table, or one JSON object with --json.\n"
      "Exit: 0 success, 1 the robot failed, was unreachable or reports state error, 2 usage or config error.");
  add_fleet_options(*app, op, false, options);
  if (auto done = parse_command_line(*app, args, out, err)) return *done;
  if (const auto problem = finish_fleet_options(*app, false, options); !problem.empty()) return usage_error(*app, problem, err);
  std::vector<swarm::SwarmNode> targets;
  if (!options.nodes.empty()) {
    if (!swarm_targets(options, targets, err)) return kExitUsage;
  } else {
    swarm::SwarmNode robot;
    robot.name = options.host;
    robot.host = options.host;
    robot.port = options.port;
    robot.token = options.token;
    apply_tls(options.tls, robot);
    targets.push_back(std::move(robot));
  }
  return run_fleet_operation(op, targets, options, out, err);
}

int run_status(std::span<const std::string> args) { return run_robot("status", args, std::cout, std::cerr); }
int run_stop(std::span<const std::string> args) { return run_robot("stop", args, std::cout, std::cerr); }
int run_command(std::span<const std::string> args) { return run_robot("command", args, std::cout, std::cerr); }

}  // namespace rcand::rcanctl
