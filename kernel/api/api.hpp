// The HTTP API's front door (docs/protocol.md §7): the route table and the middleware every request goes through
// once. Before anything else, screen() (the server calls it for every request, WebSocket upgrades included) refuses a
// browser page of another origin (docs/protocol.md §3.9). Then, in this order: message id → rate limit per address → route match
// (404/405) → authentication for the row's scope → rate limit per principal → a service's decorator, if any → the audit entry
// (audited rows) → the e-stop pre-check (motion rows) → the row's handler. Runs on the server's I/O threads and never blocks
// there: the stop handler runs inline; capability handlers run on their own workers.
#pragma once

#include <atomic>
#include <functional>
#include <string>

#include <nlohmann/json.hpp>

#include "kernel/api/router.hpp"
#include "kernel/audit/audit_log.hpp"
#include "kernel/auth/authenticator.hpp"
#include "kernel/safety/estop.hpp"
#include "libs/base/logging.hpp"
#include "libs/base/rate_limiter.hpp"
#include "libs/config/robot_config.hpp"
#include "libs/http/handler.hpp"
#include "libs/http/origin_policy.hpp"

namespace rcand::kernel {

// The bearer credential of a request: the Authorization header, or ?token= where docs/protocol.md §3 allows it
// (GET /api/stream/mjpeg, WebSocket upgrades); nullopt when it has none.
std::optional<std::string_view> request_credential(const http::Request& request);

class Api {
 public:
  Api(const config::RuntimeConfig& config, const Authenticator& auth, AuditLog& audit, const Estop& estop,
      const sdk::Clock& clock, http::OriginPolicy origins = http::OriginPolicy());

  // Startup only: routes are added before the server starts and never change afterwards.
  Router& router() noexcept { return router_; }

  // I/O thread; never blocks.
  void handle(http::Request&& request, http::Respond respond);
  // The server's screen (http::ServerOptions::screen), for every request and WebSocket upgrade on every port rcand
  // serves: 403 ORIGIN_NOT_ALLOWED for a browser page of another origin, or naming a host the robot does not know
  // (logged like other refusals); nullopt lets the request go on. Any I/O thread, the accept thread included.
  std::optional<http::Response> screen(const http::Request& request);

  // An R2R `command` (docs/protocol.md §11): runs `body` exactly as POST /api/action from `principal`, whom the R2R
  // node already authenticated: the same scope checks, 423 e-stop pre-check, audit entry and capability dispatch.
  // `done` is called once, from any thread, with the status and JSON body the request would have got. Never blocks.
  void execute_action(const Principal& principal, nlohmann::json body, std::function<void(int status, nlohmann::json body)> done);
  // Any request from `principal`, already authenticated by the caller (an R2R node, a plugin's RequestDispatcher):
  // everything after authentication runs as for HTTP. An invalid or missing x-message-id header gets one made.
  // `audit_note` joins the request's audit entry (AuditEntry::note).
  void execute(const Principal& principal, http::Request request, http::Respond respond, nlohmann::json audit_note = nullptr);
  // A request a plugin makes on a caller's behalf (RequestDispatcher), carrying that caller's credential in its
  // Authorization header: authenticated and authorized again exactly as the caller's own HTTP request would be now
  // (401 for a credential no longer accepted, 403 for scopes that no longer cover the route); only the per-address
  // rate limit is skipped (every such request comes from "plugin").
  void execute_for_caller(http::Request request, http::Respond respond, nlohmann::json audit_note = nullptr);

 private:
  void serve(http::Request&& request, const Principal* authenticated, http::Respond respond, nlohmann::json audit_note = nullptr,
             bool address_limited = true);
  // The audit entry, the e-stop pre-check and the handler (after the row's decorator, if any).
  void dispatch(const Route& route, Call& call, Reply reply);
  // The principal for `scope` (the R2R peer's own when `authenticated`), else answers 401/403 and returns false.
  bool authenticate(Call& call, const Principal* authenticated, sdk::Scope scope, const Reply& reply);
  bool admit_address(const http::Request& request, const Reply& reply);
  bool admit_principal(const Call& call, const Reply& reply);

  // One log line per refusal (429, 401, 403) would let a flood write the log at its own rate: at most
  // kRefusalLogLines a second per client address, then one line saying how many were left out.
  static constexpr std::uint32_t kRefusalLogLines = 5;
  void log_refusal(const char* logger_name, const http::Request& request, const std::string& what);

  const Authenticator& auth_;
  AuditLog& audit_;
  const Estop& estop_;
  const sdk::Clock& clock_;
  const http::OriginPolicy origins_;
  Router router_;
  std::atomic<std::uint64_t> message_counter_{0};
  RateLimiter principal_limiter_, address_limiter_;
  LogRateLimiter refusal_log_{kRefusalLogLines};
};

}  // namespace rcand::kernel
