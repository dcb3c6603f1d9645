// The optional services linked into rcand, in start order (stopped in reverse). A new in-tree service is one line
// here and a folder under services/.
#include "kernel/service.hpp"
#include "services/dashboard/dashboard_service.hpp"
#include "services/r2r/r2r_module.hpp"
#include "services/swarm_broadcast/swarm_broadcast.hpp"
#include "services/telemetry/telemetry_service.hpp"

namespace rcand::kernel {

std::vector<ServiceFactory> linked_services() {
  // swarm.yaml, one per kernel: loaded and reloaded by the swarm broadcast, read by it and by R2R (made first, but
  // reading it only once it serves).
  auto swarm = std::make_shared<swarm::LiveRegistry>();
  return {[swarm](ServiceHost& host) { return services::make_r2r(host, swarm); },
          [swarm](ServiceHost& host) { return services::make_swarm_broadcast(host, swarm); }, services::make_dashboard,
          services::make_telemetry};
}

std::vector<std::function<void(const config::RobotConfig&)>> linked_service_checks() { return {services::check_swarm_file}; }

}  // namespace rcand::kernel
