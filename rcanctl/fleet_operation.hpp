// What `rcanctl status|stop|command` and `rcanctl swarm status|stop|command` share: the options, the targets (one
// robot or swarm.yaml nodes), the parallel requests and the output (an aligned table, or one JSON object per node
// per line with --json). Exit codes: 0 every selected node succeeded, 1 partial failure, 2 usage or config error.
#pragma once

#include <cstdint>
#include <iosfwd>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "command_line.hpp"
#include "exit_codes.hpp"
#include "libs/swarm/swarm_registry.hpp"
#include "tls_options.hpp"

namespace rcand::rcanctl {

inline constexpr int kExitPartial = kExitFailure;  // some selected nodes failed

enum class Operation { Status, Stop, Command };

struct FleetOptions {
  std::vector<std::string> nodes, tags;
  std::string swarm_file = swarm::kDefaultSwarmFile;
  bool json = false;
  int timeout_ms = 0;  // 0: the operation's default (stop 400 ms, inside the 500 ms budget)
  std::string instruction;
  // One robot (rcanctl status|stop|command without --node): address and token.
  std::string host = "127.0.0.1";
  std::uint16_t port = swarm::kDefaultSwarmPort;
  std::string token;  // --token, --token-file or $RCAND_TOKEN
  std::string token_file;
  TlsOptions tls;  // one robot: --cacert/--cert/--key, https:// hosts (swarm nodes name their own `ca`)
};

// "status" | "stop" | anything else (command).
Operation operation_named(std::string_view verb);

// Declares the options of `op` (rcanctl status|stop|command, or under rcanctl swarm with `swarm_mode`) on `app`.
void add_fleet_options(CLI::App& app, Operation op, bool swarm_mode, FleetOptions& options);
// After the parse: the one-robot address, TLS and token, and what may not go together. An error message, or "".
std::string finish_fleet_options(const CLI::App& app, bool swarm_mode, FleetOptions& options);

// Runs `op` on every target in parallel and prints the result. `targets` is never empty.
int run_fleet_operation(Operation op, const std::vector<swarm::SwarmNode>& targets, const FleetOptions& options,
                        std::ostream& out, std::ostream& err);

// Targets from swarm.yaml (selection by --node/--tag), or nullopt after writing the error (exit 2) to `err`.
bool swarm_targets(const FleetOptions& options, std::vector<swarm::SwarmNode>& targets, std::ostream& err);

}  // namespace rcand::rcanctl
