#include "robot_commands.hpp"

#include <iostream>

#include "fleet_operation.hpp"

namespace rcand::rcanctl {
namespace {

constexpr std::string_view kRobotUsage =
    "usage: rcanctl status  [--host HOST] [--port PORT] (--token T | --token-file FILE) [--json] [--timeout MS]\n"
    "       rcanctl stop    [same options]\n"
    "       rcanctl command --instruction \"...\" [same options]\n"
    "       any of them with --node NAME [--swarm FILE] instead of --host/--port/--token: a node of swarm.yaml\n"
    "  HOST default 127.0.0.1, PORT default 8000, the token may also come from $RCAND_TOKEN;\n"
    "  --swarm default /etc/rcand/swarm.yaml. Output: a table, or one JSON object per node with --json.\n"
    "  Exit: 0 success, 1 the robot failed, was unreachable or reports state error, 2 usage or config error.\n"
    "  TLS: --host https://HOST[:PORT], or --cacert FILE (the CA that signed the robot's certificate; default the\n"
    "  system's CAs), --cert FILE --key FILE for mutual TLS ($RCAND_CACERT, $RCAND_CERT, $RCAND_KEY supply them).\n";

}  // namespace

int run_robot(std::string_view operation, std::span<const std::string> args, std::ostream& out, std::ostream& err) {
  const Operation op = operation_named(operation);
  FleetOptions options;
  if (auto done = parse_fleet_command(args, op, false, kRobotUsage, options, out, err)) return *done;
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
