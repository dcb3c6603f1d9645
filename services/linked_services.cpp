// The optional services linked into rcand, in start order (stopped in reverse). A new in-tree service is one line
// here and a folder under services/.
#include "kernel/service.hpp"
#include "services/dashboard/dashboard_service.hpp"
#include "services/r2r/r2r_module.hpp"
#include "services/swarm_broadcast/swarm_broadcast.hpp"
#include "services/telemetry/telemetry_service.hpp"

namespace rcand::kernel {

std::vector<ServiceFactory> linked_services() {
  return {services::make_r2r, services::make_swarm_broadcast, services::make_dashboard, services::make_telemetry};
}

}  // namespace rcand::kernel
