#include "swarm_command.hpp"

#include <iostream>

#include "fleet_operation.hpp"

namespace rcand::rcanctl {
namespace {

constexpr std::string_view kSwarmUsage =
    "usage: rcanctl swarm status  [--node NAME]... [--tag TAG]... [--swarm FILE] [--json] [--timeout MS]\n"
    "       rcanctl swarm stop    [same options]\n"
    "       rcanctl swarm command --instruction \"...\" [same options]\n"
    "  Every selected node of swarm.yaml (default /etc/rcand/swarm.yaml) is addressed directly and in parallel with\n"
    "  its own token. --node: any of the names; --tag: nodes carrying every tag. A stop waits at most 400 ms per node.\n"
    "  Output: an aligned table, or one JSON object per node per line with --json.\n"
    "  Exit: 0 every node succeeded, 1 partial failure, 2 usage or config error.\n";

}  // namespace

int run_swarm(std::span<const std::string> args, std::ostream& out, std::ostream& err) {
  if (args.empty()) {
    err << "rcanctl swarm: which operation? status, stop or command\n" << kSwarmUsage;
    return kExitUsage;
  }
  const std::string& verb = args.front();
  if (verb == "--help" || verb == "-h" || verb == "help") {
    out << kSwarmUsage;
    return kExitOk;
  }
  if (verb != "status" && verb != "stop" && verb != "command") {
    err << "rcanctl swarm: unknown operation '" << verb << "' (status, stop or command)\n" << kSwarmUsage;
    return kExitUsage;
  }
  const Operation op = operation_named(verb);
  FleetOptions options;
  if (auto done = parse_fleet_command(args.subspan(1), op, true, kSwarmUsage, options, out, err)) return *done;
  std::vector<swarm::SwarmNode> targets;
  if (!swarm_targets(options, targets, err)) return kExitUsage;
  return run_fleet_operation(op, targets, options, out, err);
}

int run_swarm(std::span<const std::string> args) { return run_swarm(args, std::cout, std::cerr); }

}  // namespace rcand::rcanctl
