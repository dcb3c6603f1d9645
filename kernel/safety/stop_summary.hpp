// The e-stop as people and tools read it (GET /api/estop, the telemetry frames' "estop"; docs/protocol.md §6.7): the
// fields GET /api/estop always had, who stopped the robot and how, and one sentence that says so in words.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "kernel/safety/estop.hpp"

namespace rcand::kernel {

// "Stopped by dev-owner from the dashboard", "Stopped by plugin org.rcand.nav (nav): obstacle at 12 cm", "Latched at
// startup: ..."; empty when not latched. No clock time: each reader shows since_ms in its own time zone.
std::string describe_stop(const Estop::Snapshot& snapshot);

// {"estopped", "since_ms", "reason", "source", "principal", "origin", "from", "summary"}: nulls when not latched,
// principal and from null when there is none.
nlohmann::json estop_document(const Estop::Snapshot& snapshot);

}  // namespace rcand::kernel
