// The capabilities' endpoints (RCAN §9, docs/protocol.md §7): as each capability comes up, the SDK contract's route table
// (rcand/sdk/contract/door.hpp, the one the fake host serves): one row per route a running capability registered
// (standard ones at their mounts, custom ones under /api/cap/<name>, each /api/action type its own), and fallback
// rows that answer for a capability that is not declared (404 CAPABILITY_NOT_FOUND), out of service (503) or has no
// such route. POST /api/action picks its type's row by the body's "type".
// Handlers run on the capability's own worker, answered within runtime.handler_timeout_ms.
#pragma once

#include <chrono>

#include "kernel/api/router.hpp"
#include "kernel/audit/audit_log.hpp"
#include "kernel/auth/authenticator.hpp"
#include "kernel/plugins/plugin_runtime.hpp"
#include "kernel/registry/capability_registry.hpp"
#include "kernel/safety/estop.hpp"
#include "libs/base/slot_table.hpp"
#include "libs/base/worker_thread.hpp"

namespace rcand::kernel {

struct CapabilityRouteDeps {
  const CapabilityRegistry& registry;
  PluginRuntime& runtime;
  AuditLog& audit;
  const Estop& estop;
  WorkerThread& timers;  // handler timeouts
  std::chrono::milliseconds handler_timeout;
  // Streamed answers held at once (runtime.max_streams_per_principal, max_streams_per_address; kernel/auth/slots.hpp):
  // a stream route's multipart answer takes a slot when it starts, or is refused 429 TOO_MANY_STREAMS instead.
  SlotTable& streams;
  const Authenticator& auth;  // whether auth mode is open
};

// The capabilities' rows (the router's group "capabilities") for the capabilities up now, replacing the ones before:
// at startup, and again as each capability comes up. A capability still starting has only its fallback rows, which
// answer 503 STARTING. The dependencies outlive the router's use of them.
void install_capability_routes(Router& router, const CapabilityRouteDeps& deps);

// The rows add_capability_routes serves for `instance`, for GET /api/status (docs/protocol.md §7.2):
// [{"method", "path", "scope", "type"? (POST /api/action rows), "motion"?, "stream"?}].
nlohmann::json served_routes(const CapabilityInstance& instance);

}  // namespace rcand::kernel
