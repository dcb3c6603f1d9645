// R2R messages as a Prometheus counter (rcand/sdk/interfaces/metrics.hpp, offered by the telemetry service):
//   rcand_r2r_messages_total{direction, type, transport}   direction: received (accepted: valid and authorized) or
//                                                          sent (taken by a transport, "reply"/"route" included)
#pragma once

#include "kernel/plugins/service_directory.hpp"
#include "services/r2r/r2r_node.hpp"

namespace rcand::services::r2r {

// The node's message observer, recording into whatever offers sdk::Metrics at each message (nothing when none does).
R2rNode::MessageObserver message_metrics(const kernel::ServiceDirectory& directory);

}  // namespace rcand::services::r2r
