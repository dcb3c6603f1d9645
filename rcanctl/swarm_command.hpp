// `rcanctl swarm status|command|stop [--node NAME] [--tag TAG] [--swarm FILE] [--json]` (seed §15.3): the controller
// addresses every selected node directly and in parallel, each with its own token from swarm.yaml.
#pragma once

#include <iosfwd>
#include <span>
#include <string>

namespace rcand::rcanctl {

int run_swarm(std::span<const std::string> args);
int run_swarm(std::span<const std::string> args, std::ostream& out, std::ostream& err);

}  // namespace rcand::rcanctl
