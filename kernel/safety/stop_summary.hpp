// The e-stop as people and tools read it (GET /api/estop, the telemetry frames' "estop"; docs/protocol.md §6.7): the
// fields GET /api/estop always had, who stopped the robot and how, and one sentence that says so in words.
#pragma once

#include <nlohmann/json.hpp>

#include "kernel/safety/estop.hpp"

namespace rcand::kernel {

// {"estopped", "since_ms", "reason", "source", "principal", "origin", "from", "summary"}: nulls when not latched,
// principal and from null when there is none; the summary is describe_stop() (libs/base/stop_origin.hpp).
nlohmann::json estop_document(const Estop::Snapshot& snapshot);

}  // namespace rcand::kernel
