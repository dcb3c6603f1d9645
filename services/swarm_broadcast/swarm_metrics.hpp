// §15 swarm results as Prometheus counters (rcand/sdk/interfaces/metrics.hpp, offered by the telemetry service):
//   rcand_swarm_broadcasts_total{kind, result}        kind: stop, command; result: ok (every node ok), partial, failed
//   rcand_swarm_node_results_total{kind, outcome}     per node of a broadcast, and per-node stops from the swarm table
//                                                     (kind node_stop); outcome: ok, not_executed (a latched node's
//                                                     acknowledgement), failed (answered, not ok), unreachable
#pragma once

#include <nlohmann/json.hpp>

#include <string_view>

#include "kernel/plugins/service_directory.hpp"

namespace rcand::services {

void declare_swarm_metrics(const kernel::ServiceDirectory& directory) noexcept;
// One finished broadcast: its report's "nodes" (swarm::broadcast_document).
void record_broadcast(const kernel::ServiceDirectory& directory, std::string_view kind, const nlohmann::json& nodes) noexcept;
// One node's entry (swarm::node_entry) of a per-node stop.
void record_node_stop(const kernel::ServiceDirectory& directory, const nlohmann::json& node) noexcept;

}  // namespace rcand::services
