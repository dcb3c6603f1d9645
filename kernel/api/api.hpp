// The HTTP API (docs/protocol.md §7): routing, authentication, the audit record before dispatch, the e-stop pre-check for
// motion routes, and dispatch to capability workers. Runs on the server's I/O threads and never blocks there:
// capability handlers run on their own workers; the stop path runs inline and touches no queue or worker.
#pragma once

#include <atomic>
#include <chrono>
#include <functional>
#include <string>

#include "kernel/auth/authenticator.hpp"
#include "kernel/config/robot_config.hpp"
#include "kernel/audit/audit_log.hpp"
#include "kernel/registry/capability_registry.hpp"
#include "kernel/safety/estop.hpp"
#include "libs/base/logging.hpp"
#include "kernel/plugins/plugin_runtime.hpp"
#include "kernel/api/rate_limiter.hpp"
#include "libs/base/worker_thread.hpp"
#include "libs/http/server.hpp"
#include "libs/swarm/fan_out.hpp"
#include "libs/swarm/swarm_registry.hpp"

namespace rcand::kernel {

class R2rService;  // core/r2r_service.hpp

struct ApiContext {
  const RobotConfig& config;
  const Authenticator& auth;
  const CapabilityRegistry& registry;
  const PluginHost& host;
  PluginRuntime& runtime;
  Estop& estop;
  AuditLog& audit;
  const sdk::Clock& clock;
  WorkerThread& timers;  // handler timeouts
  std::chrono::milliseconds handler_timeout;
  std::string version;
  std::int64_t started_us = 0;
  std::atomic<std::uint16_t> port{0};
  // §15 swarm: the peers of runtime.swarm_file (none when absent) and the fan-out client; both outlive the Api.
  // Atomic: a config reload (SIGHUP) swaps in a new registry (the old one is kept alive) while requests run.
  std::atomic<const swarm::SwarmRegistry*> swarm{nullptr};
  swarm::FanOut* fan_out = nullptr;
  // R2R (docs/protocol.md §11) for the /api/r2r/ routes; null when runtime.r2r.enabled is off. Outlives the Api's requests.
  R2rService* r2r = nullptr;
};

class Api {
 public:
  explicit Api(ApiContext& context);
  // I/O thread; never blocks.
  void handle(http::Request&& request, http::Respond respond);

  // An R2R `command` (docs/protocol.md §11): runs `body` exactly as POST /api/action from `principal`, whom the R2R node already
  // authenticated: the same scope checks, 423 e-stop pre-check, audit entry and capability dispatch. `done` is called
  // once, from any thread, with the HTTP status and JSON body the request would have got. Never blocks.
  void execute_action(const Principal& principal, nlohmann::json body,
                      std::function<void(int status, nlohmann::json body)> done);

  // idle | running | error | estop (docs/protocol.md §5 status values).
  std::string robot_state() const;
  nlohmann::json status_document() const;
  nlohmann::json discovery_document() const;

 private:
  struct Caller;
  // handle(), with `authenticated` (non-null) standing in for the Authorization header.
  void dispatch(http::Request&& request, const Principal* authenticated, http::Respond respond);
  // §15 broadcasts of POST /api/stop and POST /api/command, and the e-stop acknowledgement of forwarded commands.
  // Returns false when the request is not one (the normal path handles it). Never blocks: the answer comes from
  // the fan-out's completion.
  bool handle_swarm(http::Request& request, const Caller& caller, const std::function<bool(sdk::Scope)>& authorize,
                    const http::Respond& reply);
  bool is_self(const swarm::SwarmNode& node) const;
  void handle_kernel(const std::string& endpoint, http::Request& request, const Caller& caller, http::Respond& respond);
  void handle_capability(CapabilityInstance& instance, const sdk::Route& route, http::Request& request,
                         nlohmann::json body, const Caller& caller, http::Respond respond);

  // The state from the facts already gathered; nav_running from nav's own status.
  std::string robot_state(bool nav_running) const;
  bool nav_running() const;

  // One log line per refusal (429, 401, 403) would let a flood write the log at its own rate: at most
  // kRefusalLogLines a second per client address, then one line saying how many were left out.
  static constexpr std::uint32_t kRefusalLogLines = 5;
  void log_refusal(const char* logger_name, const http::Request& request, const std::string& what);

  ApiContext& ctx_;
  std::atomic<std::uint64_t> message_counter_{0};
  RateLimiter principal_limiter_, address_limiter_;
  LogRateLimiter refusal_log_{kRefusalLogLines};
  // What /api/status says that cannot change after startup (identity, plugin table), built once: the status
  // endpoint is the one clients poll hardest.
  nlohmann::json static_status_;
};

}  // namespace rcand::kernel
