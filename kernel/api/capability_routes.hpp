// The capabilities' endpoints (RCAN §9, docs/protocol.md §7): at startup, the SDK contract's route table
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

// Startup, after the capabilities started. The dependencies outlive the router's use of them.
void add_capability_routes(Router& router, const CapabilityRouteDeps& deps);

// The rows add_capability_routes serves for `instance`, for GET /api/status (docs/protocol.md §7.2):
// [{"method", "path", "scope", "type"? (POST /api/action rows), "motion"?, "stream"?}].
nlohmann::json served_routes(const CapabilityInstance& instance);

}  // namespace rcand::kernel
