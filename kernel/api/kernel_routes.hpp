// The kernel's own endpoints (docs/protocol.md §7): health, status, discovery, the e-stop, the audit log, plugins
// and drivers. One row each in add_kernel_routes(), one named handler each in kernel_routes.cpp.
#pragma once

#include <functional>
#include <memory>
#include <string>

#include <nlohmann/json.hpp>

#include "kernel/api/router.hpp"
#include "kernel/audit/audit_log.hpp"
#include "kernel/plugins/plugin_host.hpp"
#include "kernel/plugins/plugin_runtime.hpp"
#include "kernel/safety/estop.hpp"
#include "kernel/status/status_board.hpp"

namespace rcand::kernel {

struct KernelRouteDeps {
  const sdk::Clock& clock;
  Estop& estop;
  AuditLog& audit;
  const PluginHost& host;
  PluginRuntime& runtime;
  std::string version;
  std::int64_t started_us = 0;
  StatusBoard& status;                        // the GET /api/status snapshot
  std::function<nlohmann::json()> discovery;  // GET /api/discovery
  // POST /api/plugins/<id>/reload as `principal`: `done` is called once, from any thread, with the status and body.
  std::function<void(const std::string& id, const std::string& principal, std::function<void(int, nlohmann::json)> done)>
      reload_plugin;
};

// Startup. The dependencies outlive the router's use of them (the Kernel owns both).
void add_kernel_routes(Router& router, const KernelRouteDeps& deps);

}  // namespace rcand::kernel
