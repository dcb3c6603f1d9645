// R2R as a service of the kernel (docs/protocol.md §11): the node and its transports when runtime.r2r.enabled, the
// /api/r2r/ rows either way (404 R2R_DISABLED when off), WS /ws/r2r on the robot's own port, and the plugins' R2R
// links.
#pragma once

#include <memory>

#include "kernel/service.hpp"
#include "libs/swarm/live_registry.hpp"

namespace rcand::services {

// `swarm`: swarm.yaml as now (the swarm-broadcast service loads it), the robots a relay or a WebSocket dial reaches.
std::unique_ptr<kernel::Service> make_r2r(kernel::ServiceHost& host, std::shared_ptr<const swarm::LiveRegistry> swarm);

}  // namespace rcand::services
