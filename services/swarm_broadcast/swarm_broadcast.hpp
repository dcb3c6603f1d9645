// §15 swarm broadcasts (docs/protocol.md §9): POST /api/stop and POST /api/command with X-Swarm-Broadcast (or
// "broadcast": true) run here and on every selected peer of runtime.swarm_file, answered with one report. The local
// stop happens first, inline, before anything is forwarded; peers get 300 ms each so the whole stays inside 500 ms.
// A forwarded command on a node in e-stop is acknowledged and not executed (§15.5: the e-stop is always local).
// Wraps the kernel's rows; the kernel knows nothing of it. Also the swarm table (swarm_table.hpp): GET /api/swarm and
// POST /api/swarm/<node>/stop, on the same fan-out.
#pragma once

#include <spdlog/logger.h>

#include <filesystem>
#include <memory>

#include "kernel/service.hpp"
#include "libs/swarm/live_registry.hpp"

namespace rcand::services {

// Always on: without a swarm file a broadcast reaches this robot only. Loads runtime.swarm_file into `swarm` (a
// malformed file: StartupError) and reloads it on SIGHUP (the key is live).
std::unique_ptr<kernel::Service> make_swarm_broadcast(kernel::ServiceHost& host, std::shared_ptr<swarm::LiveRegistry> swarm);

// runtime.swarm_file (§15.2) as startup reads it: no file means no peers; a malformed one throws StartupError naming
// the key. `log` (may be null) is told what was read.
swarm::SwarmRegistry read_swarm_file(const std::filesystem::path& file, const std::shared_ptr<spdlog::logger>& log);
// --check-config: the swarm file read as at startup (Kernel::check runs it through KernelOptions::service_checks).
void check_swarm_file(const config::RobotConfig& config);

}  // namespace rcand::services
