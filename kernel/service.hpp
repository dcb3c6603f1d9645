// Optional in-tree services (services/): R2R, the swarm broadcast. Each one adds its routes and its WebSocket
// upgrade to the kernel's tables and is started and stopped in list order (stopped in reverse, right after the
// e-stop latch at shutdown). The kernel never includes a service: the binary that links them hands their factories
// to the Kernel (KernelOptions::services; rcand's main passes linked_services()).
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "kernel/api/api.hpp"
#include "kernel/api/router.hpp"
#include "kernel/audit/audit_log.hpp"
#include "kernel/auth/authenticator.hpp"
#include "kernel/plugins/service_directory.hpp"
#include "kernel/registry/capability_registry.hpp"
#include "kernel/safety/estop.hpp"
#include "libs/config/robot_config.hpp"
#include "libs/http/server_options.hpp"

namespace rcand::kernel {

// What the kernel lends a service. Everything outlives the service.
struct ServiceHost {
  const config::RobotConfig& config;
  const Authenticator& auth;
  Estop& estop;
  AuditLog& audit;
  const sdk::Clock& clock;
  const CapabilityRegistry& registry;
  Api& api;  // execute_action(): a command through the same middleware as HTTP
  std::chrono::milliseconds handler_timeout;
  std::function<nlohmann::json()> status_document;  // GET /api/status as a document, from the status snapshot
  std::function<std::string()> robot_state;         // its "state" as now, without the document (StatusBoard)
  const std::atomic<std::uint16_t>& port;           // the bound HTTP port (0 until start)
  // The services plugin instances offer (rcand/sdk/services.hpp): sdk::find<T>(plugin_services) at use time, any
  // thread, never blocks; null while nothing offers T (the plugins start after the services are made). A service
  // may offer one too (telemetry offers sdk::Metrics, R2R sdk::R2rLinks), with itself as the owner, withdrawn when
  // it is destroyed.
  ServiceDirectory& plugin_services;
};

// What a service takes from a config reloaded by SIGHUP (Kernel::reload).
struct ServiceReload {
  std::function<void()> apply;         // run once every part of the reload was checked; must not throw
  std::vector<std::string> live_keys;  // the config keys it applies while serving (and the keys under them)
};

class Service {
 public:
  virtual ~Service() = default;
  virtual std::string_view name() const noexcept = 0;
  // Startup, after the plugins started: this service's rows (or wraps of kernel rows).
  virtual void add_routes(Router&) {}
  // The HTTP server's WebSocket upgrade hook this service serves (one per server for now), or empty.
  virtual http::UpgradeHandler upgrade() { return {}; }
  // After the HTTP server bound its port. Throws StartupError naming the setting at fault.
  virtual void start(std::uint16_t /*http_port*/) {}
  // Plugin instances started (each capability as it comes up; all of them at once in an embedded kernel) or were
  // reloaded: the services plugins offer may have changed. One call at a time, off the serving threads.
  virtual void capabilities_changed() noexcept {}
  // SIGHUP: reads and checks what this service takes from `next` (files it names) before anything changes. Throws
  // StartupError naming the key at fault: then nothing of the reload is applied.
  virtual ServiceReload prepare_reload(const config::RobotConfig& /*next*/) { return {}; }
  // Shutdown, after the e-stop latch: nothing of this service runs or sends afterwards. Idempotent.
  virtual void stop() noexcept {}
};

// nullptr: the service is not enabled by this config. Throws StartupError naming the key at fault.
using ServiceFactory = std::function<std::unique_ptr<Service>(ServiceHost&)>;

// Defined by the binary that links the services (services/linked_services.cpp), not by the kernel. Checks: what
// the services read besides config keys (files), each read as at startup; a problem throws StartupError (--check-config).
std::vector<ServiceFactory> linked_services();
std::vector<std::function<void(const config::RobotConfig&)>> linked_service_checks();

}  // namespace rcand::kernel
