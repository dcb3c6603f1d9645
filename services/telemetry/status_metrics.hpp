// The /metrics families read from GET /api/status's document (the status snapshot): identity, uptime, the latch,
// plugin, capability and driver states, nav. A state is exposed the Prometheus way: one sample per possible state,
// 1 for the current one and 0 for the others, so a query can alert on `== 1` without knowing the label set.
#pragma once

#include <nlohmann/json.hpp>

#include "services/telemetry/metrics_text.hpp"

namespace rcand::services::telemetry {

void write_status_metrics(MetricsText& out, const nlohmann::json& status);

}  // namespace rcand::services::telemetry
