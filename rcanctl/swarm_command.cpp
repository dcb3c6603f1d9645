#include "swarm_command.hpp"

#include <iostream>
#include <utility>
#include <vector>

#include "command_line.hpp"
#include "fleet_operation.hpp"

namespace rcand::rcanctl {
int run_swarm(std::span<const std::string> args, std::ostream& out, std::ostream& err) {
  const auto app = make_command_app(
      "rcanctl swarm",
      "Every selected node of swarm.yaml, addressed directly and in parallel with its own token. --node: any of the\n"
      "names; --tag: nodes carrying every tag. A stop waits at most 400 ms per node.",
      "Output: an aligned table, or one JSON object per node per line with --json.\n"
      "Exit: 0 every node succeeded, 1 partial failure, 2 usage or config error.");
  constexpr std::pair<const char*, const char*> kOperations[] = {
      {"status", "every node's status"}, {"stop", "latch every node's e-stop"}, {"command", "send every node an instruction"}};
  std::vector<FleetOptions> options(3);  // one per operation: each declares its own options
  for (std::size_t i = 0; i < 3; ++i)
    add_fleet_options(*app->add_subcommand(kOperations[i].first, kOperations[i].second), operation_named(kOperations[i].first),
                      true, options[i]);
  app->require_subcommand(1);
  if (auto done = parse_command_line(*app, args, out, err)) return *done;
  const CLI::App* chosen = app->get_subcommands().front();
  const Operation op = operation_named(chosen->get_name());
  FleetOptions& chosen_options = options[static_cast<std::size_t>(op)];
  std::vector<swarm::SwarmNode> targets;
  if (!swarm_targets(chosen_options, targets, err)) return kExitUsage;
  return run_fleet_operation(op, targets, chosen_options, out, err);
}

int run_swarm(std::span<const std::string> args) { return run_swarm(args, std::cout, std::cerr); }

}  // namespace rcand::rcanctl
