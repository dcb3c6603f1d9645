// §15 swarm broadcasts (docs/protocol.md §9): POST /api/stop and POST /api/command with X-Swarm-Broadcast (or
// "broadcast": true) run here and on every selected peer of runtime.swarm_file, answered with one report. The local
// stop happens first, inline, before anything is forwarded; peers get 300 ms each so the whole stays inside 500 ms.
// A forwarded command on a node in e-stop is acknowledged and not executed (§15.5: the e-stop is always local).
// Wraps the kernel's rows; the kernel knows nothing of it. Also the swarm table (swarm_table.hpp): GET /api/swarm and
// POST /api/swarm/<node>/stop, on the same fan-out.
#pragma once

#include <memory>

#include "kernel/service.hpp"

namespace rcand::services {

// Always on: without a swarm file a broadcast reaches this robot only.
std::unique_ptr<kernel::Service> make_swarm_broadcast(kernel::ServiceHost& host);

}  // namespace rcand::services
