// Telemetry and metrics as a service of the kernel (issue 18): WS /ws/telemetry (docs/protocol.md §7.10, a frame
// every 200 ms and one pushed at once on an e-stop latch or clear) and GET /metrics (Prometheus text, scope
// status; also unauthenticated on 127.0.0.1:runtime.telemetry.metrics_port when that is set). Both read the status
// snapshot (ServiceHost::status_document), never plugin code.
#pragma once

#include <memory>

#include "kernel/service.hpp"

namespace rcand::services {

std::unique_ptr<kernel::Service> make_telemetry(kernel::ServiceHost& host);

}  // namespace rcand::services
