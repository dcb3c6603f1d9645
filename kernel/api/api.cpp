#include "kernel/api/api.hpp"

#include <algorithm>
#include <array>
#include <charconv>
#include <mutex>

#include <boost/asio/ip/address.hpp>

#include "kernel/api/json_body.hpp"
#include "libs/base/logging.hpp"
#include "services/r2r/r2r_routes.hpp"
#include "kernel/plugins/guarded.hpp"
#include "libs/swarm/broadcast_report.hpp"
#include "libs/swarm/node_selection.hpp"
#include "libs/base/bounded_text.hpp"

namespace rcand::kernel {
namespace {

using nlohmann::json;
using sdk::Scope;

struct KernelEndpoint {
  std::string_view method, path;
  Scope scope;
};
constexpr std::array<KernelEndpoint, 8> kKernelEndpoints{{
    {"GET", "/health", Scope::None},
    {"GET", "/api/status", Scope::Status},
    {"GET", "/api/discovery", Scope::None},
    {"POST", "/api/stop", Scope::Status},
    {"GET", "/api/estop", Scope::Status},
    {"POST", "/api/estop/clear", Scope::Config},
    {"GET", "/api/audit", Scope::Config},
    {"GET", "/api/plugins", Scope::Status},
}};
constexpr std::string_view kDriversPrefix = "/api/drivers/";
constexpr std::string_view kCustomPrefix = "/api/cap/";
constexpr std::string_view kActionPath = "/api/action";
constexpr std::size_t kMaxAuditLimit = 10000;

// Where each standard capability's endpoints live (§9.2, docs/protocol.md §7); /api/action is routed by body "type".
struct StandardPrefix {
  std::string_view prefix, capability;
  bool exact;
};
constexpr std::array<StandardPrefix, 4> kStandardPrefixes{{
    {"/api/nav/", "nav", false},
    {"/api/command", "chat", true},
    {"/api/stream/", "vision", false},
    {"/api/depth/", "vision", false},
}};
struct ActionType {
  std::string_view type, capability;
};
constexpr std::array<ActionType, 4> kActionTypes{{{"move", "teleop"}, {"stop", "teleop"}, {"grip", "arm"}, {"arm_pose", "arm"}}};

http::Response json_response(int status, const json& body) {
  http::Response response;
  response.status = status;
  response.body = body.dump(-1, ' ', false, json::error_handler_t::replace);
  return response;
}

http::Response error(int status, std::string_view code, std::string message, json extra = json::object()) {
  return json_response(status, sdk::Response::error(status, std::string(code), std::move(message), std::move(extra)).body);
}

// A plugin's answer, with the docs/protocol.md §4 error shape guaranteed on every non-2xx status.
http::Response from_plugin(const sdk::Response& answer) {
  if (answer.status < 100 || answer.status > 599) return error(500, "INTERNAL", "capability answered an invalid status");
  if (answer.status < 300) return json_response(answer.status, answer.body);
  json body = answer.body.is_object() ? answer.body : json::object();
  if (!body.contains("error")) body["error"] = "request failed";
  if (!body.contains("code")) body["code"] = answer.status >= 500 ? "INTERNAL" : "BAD_REQUEST";
  body["status"] = answer.status;
  return json_response(answer.status, body);
}

bool valid_message_id(std::string_view id) {
  if (id.empty() || id.size() > 64) return false;
  for (char c : id)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-' && c != '_' && c != '.') return false;
  return true;
}

// True only for a JSON true: a plugin's or a peer's "running": "yes" is not a crash, and not true either.
bool is_true(const json& object, const char* key) {
  if (!object.is_object()) return false;
  const auto found = object.find(key);
  return found != object.end() && found->is_boolean() && found->get<bool>();
}

// The e-stop paths (docs/protocol.md §6.4): never rate-limited, never queued behind other work.
bool is_estop_path(const http::Request& request) {
  return (request.method == "POST" && (request.path == "/api/stop" || request.path == "/api/estop/clear")) ||
         (request.method == "GET" && request.path == "/api/estop");
}

// "127.0.0.1:54321" -> "127.0.0.1", "[::1]:54321" -> "::1": the rate-limit key of a client address.
std::string client_address(const std::string& remote) {
  if (!remote.empty() && remote.front() == '[') return remote.substr(1, remote.find(']') - 1);
  return remote.substr(0, remote.rfind(':'));
}

http::Response too_many_requests(const std::string& who, double per_s, std::chrono::milliseconds wait) {
  const auto retry_after_s = std::max<std::int64_t>(1, (wait.count() + 999) / 1000);
  json limit = per_s;
  auto response = error(429, "RATE_LIMITED", "too many requests from " + who + " (limit " + limit.dump() + " per second)",
                        {{"retry_after_s", retry_after_s}});
  response.headers.emplace_back("Retry-After", std::to_string(retry_after_s));
  return response;
}

Scope stricter(Scope a, Scope b) { return sdk::minimum_role(a) >= sdk::minimum_role(b) ? a : b; }

std::string scope_list(Scope scope) { return std::string(sdk::scope_name(scope)); }

}  // namespace

Api::Api(ApiContext& context)
    : ctx_(context),
      principal_limiter_({context.config.runtime.rate_limit_principal_per_s, context.config.runtime.rate_limit_burst_s}),
      address_limiter_({context.config.runtime.rate_limit_address_per_s, context.config.runtime.rate_limit_burst_s}) {
  const auto& identity = ctx_.registry.identity();
  json plugins = json::array();
  for (const auto& record : ctx_.host.records()) {
    json item{{"id", record->id}, {"version", record->version}, {"state", std::string(to_string(record->state))}};
    if (!record->reason.empty()) item["reason"] = record->reason;
    plugins.push_back(std::move(item));
  }
  static_status_ = {{"ruri", identity.ruri},          {"name", identity.name},        {"version", ctx_.version},
                    {"rcan_version", kRcanVersion}, {"caps", ctx_.registry.names()}, {"plugins", std::move(plugins)}};
}

struct Api::Caller {
  std::string principal;
  sdk::Role role = sdk::Role::Guest;
  std::string message_id;
};

void Api::log_refusal(const char* logger_name, const http::Request& request, const std::string& what) {
  const std::string address = client_address(request.remote);
  const auto verdict = refusal_log_.admit(address);
  if (!verdict.log) return;
  auto log = logger(logger_name);
  if (verdict.suppressed > 0)
    log->warn("{} more refusals for {} not logged (more than {} a second)", verdict.suppressed, address, kRefusalLogLines);
  log->warn("{} {} from {}: {}", bounded_text(request.method), bounded_text(request.path), request.remote, what);
}

void Api::handle(http::Request&& request, http::Respond respond) { dispatch(std::move(request), nullptr, std::move(respond)); }

void Api::execute_action(const Principal& principal, json body, std::function<void(int, json)> done) {
  http::Request request;
  request.method = "POST";
  request.target = request.path = std::string(kActionPath);
  request.body = body.dump(-1, ' ', false, json::error_handler_t::replace);
  request.remote = "r2r";
  request.headers["x-message-id"] = "r2r-" + std::to_string(ctx_.clock.wall_ms()) + "-" + std::to_string(++message_counter_);
  dispatch(std::move(request), &principal, [done = std::move(done)](http::Response response) {
    json answer = json::parse(response.body, nullptr, false);
    done(response.status, answer.is_discarded() ? json::object() : std::move(answer));
  });
}

void Api::dispatch(http::Request&& request, const Principal* authenticated, http::Respond respond) {
  Caller caller;
  if (auto id = request.header("x-message-id"); id && valid_message_id(*id)) caller.message_id = std::string(*id);
  else caller.message_id = "m-" + std::to_string(ctx_.clock.wall_ms()) + "-" + std::to_string(++message_counter_);

  // Every answer carries the message id, so a client can find its request in the audit log.
  auto reply = [respond, id = caller.message_id](http::Response response) mutable {
    response.headers.emplace_back("X-Message-Id", id);
    respond(std::move(response));
  };

  // Rate limits (docs/protocol.md §6.4): per client address before anything else, per principal once authenticated. The e-stop
  // paths are exempt; an R2R command comes from the R2R node, which bounds its peers itself.
  const bool limited = !is_estop_path(request);
  if (limited && authenticated == nullptr) {
    const std::string address = client_address(request.remote);
    if (auto wait = address_limiter_.admit(address, ctx_.clock.now_us())) {
      log_refusal("kernel.api", request, "address " + address + " over its rate limit (429)");
      reply(too_many_requests("address " + address, address_limiter_.limit().per_s, *wait));
      return;
    }
  }
  bool principal_admitted = !limited;
  auto admit_principal = [&](const std::string& name) {
    if (principal_admitted || name == "anonymous") return true;
    if (auto wait = principal_limiter_.admit(name, ctx_.clock.now_us())) {
      log_refusal("kernel.api", request, "principal '" + name + "' over its rate limit (429)");
      reply(too_many_requests("principal '" + name + "'", principal_limiter_.limit().per_s, *wait));
      return false;
    }
    principal_admitted = true;
    return true;
  };

  // Authentication for `scope`; on failure answers and returns false.
  auto authorize = [&](Scope scope) {
    if (authenticated != nullptr) {  // an R2R peer, authenticated by the R2R node: only its scopes are checked here
      const auto& scopes = authenticated->scopes;
      if (scope != Scope::None && std::find(scopes.begin(), scopes.end(), scope) == scopes.end()) {
        reply(error(403, "INSUFFICIENT_PRIVILEGES", "principal '" + authenticated->name + "' lacks scope '" + scope_list(scope) + "'",
                    {{"required_scope", scope_list(scope)}}));
        return false;
      }
      caller.principal = authenticated->name;
      caller.role = authenticated->role;
      return admit_principal(caller.principal);
    }
    std::optional<std::string_view> bearer;
    if (auto header = request.header("authorization")) bearer = bearer_token(*header);
    else if (auto token = request.query.find("token");
             token != request.query.end() && (request.path == "/api/stream/mjpeg" || request.path.rfind("/ws/", 0) == 0))
      bearer = token->second;  // docs/protocol.md §3: ?token= only where clients cannot set headers
    const auto now_s = ctx_.clock.wall_ms() / 1000;
    auto verdict = ctx_.auth.authorize(bearer, scope, now_s);
    if (auto* failure = std::get_if<AuthError>(&verdict)) {
      log_refusal("kernel.auth", request, std::to_string(failure->status) + " (" + failure->message + ")");
      json extra = json::object();
      if (failure->status == 403) extra["required_scope"] = scope_list(scope);
      reply(error(failure->status, failure->code, failure->message, extra));
      return false;
    }
    auto& principal = std::get<Principal>(verdict);
    caller.principal = principal.name;
    caller.role = principal.role;
    return admit_principal(caller.principal);
  };

  // §15: broadcasts and swarm-forwarded commands (docs/protocol.md §9).
  if (request.method == "POST" && (request.path == "/api/stop" || request.path == "/api/command") &&
      handle_swarm(request, caller, authorize, reply))
    return;

  // R2R operator routes (docs/protocol.md §11): scope per route; unknown ones answer without authentication, like other 404s.
  if (request.path.rfind(kR2rRoutePrefix, 0) == 0) {
    if (const auto scope = r2r_route_scope(request.method, request.path); scope && !authorize(*scope)) return;
    handle_r2r_route(ctx_, request, caller.principal, caller.message_id, reply);
    return;
  }

  // 1. The kernel's own endpoints.
  bool path_known = false;
  std::vector<std::string> allowed;
  for (const auto& endpoint : kKernelEndpoints) {
    if (endpoint.path != request.path) continue;
    path_known = true;
    allowed.emplace_back(endpoint.method);
    if (endpoint.method != request.method) continue;
    if (!authorize(endpoint.scope)) return;
    http::Respond forward = reply;
    handle_kernel(std::string(endpoint.path), request, caller, forward);
    return;
  }
  if (path_known) {
    reply(error(405, "METHOD_NOT_ALLOWED", bounded_text(request.method) + " is not allowed on " + request.path,
                {{"allowed", allowed}}));
    return;
  }
  if (request.path.rfind(kDriversPrefix, 0) == 0) {
    if (request.method != "GET") {
      reply(error(405, "METHOD_NOT_ALLOWED", "only GET is allowed on " + bounded_text(request.path), {{"allowed", {"GET"}}}));
      return;
    }
    if (!authorize(Scope::Status)) return;
    const std::string id = request.path.substr(kDriversPrefix.size());
    for (const auto& driver : ctx_.runtime.drivers()) {
      if (driver.id != id) continue;
      auto status = ctx_.runtime.status_of(driver);  // first: a status() that hangs fails the driver
      json doc{{"id", driver.id}, {"protocol", driver.protocol}, {"plugin", driver.plugin_id},
               {"state", driver.health.failed() ? "failed" : "ok"}};
      if (driver.health.failed()) doc["reason"] = driver.health.reason();
      if (status) doc["status"] = std::move(*status);
      reply(json_response(200, doc));
      return;
    }
    reply(error(404, "NOT_FOUND", "no driver '" + bounded_text(id) + "'"));
    return;
  }

  // 2. Capability endpoints: which capability does this path belong to?
  std::string capability;
  std::string subpath;
  const bool is_action = request.path == kActionPath;
  const bool is_custom = request.path.rfind(kCustomPrefix, 0) == 0;
  if (is_custom) {
    const std::string rest = request.path.substr(kCustomPrefix.size());
    const auto slash = rest.find('/');
    capability = rest.substr(0, slash);
    subpath = slash == std::string::npos ? "" : rest.substr(slash);
    if (find_standard_capability(capability) != nullptr) {  // standard ones have their own endpoints
      reply(error(404, "NOT_FOUND", "'" + bounded_text(capability) + "' is a standard capability; use its standard endpoint"));
      return;
    }
  } else if (!is_action) {
    for (const auto& prefix : kStandardPrefixes) {
      if (prefix.exact ? request.path == prefix.prefix : request.path.rfind(prefix.prefix, 0) == 0) {
        capability = prefix.capability;
        break;
      }
    }
  }
  if (capability.empty() && !is_action) {
    reply(error(404, "NOT_FOUND", "no endpoint " + bounded_text(request.path)));
    return;
  }

  // Custom capabilities need at least control (§9.4). On a standard capability's endpoints reading needs status and
  // anything else control (docs/protocol.md §7: GET /api/nav/status, POST /api/nav/waypoint, POST /api/command), checked before
  // whether the capability is declared: a caller without the scope learns nothing about this robot's capabilities.
  // A route may ask for more, checked once it is known.
  const bool reads = request.method == "GET" || request.method == "HEAD";
  const Scope base_scope = is_action || !reads ? Scope::Control
                           : is_custom         ? CapabilityRegistry::minimum_scope(capability)
                                               : Scope::Status;
  if (!authorize(base_scope)) return;

  JsonBody body = parse_json_body(request.body);
  if (!body.error.empty()) {
    reply(error(400, "BAD_REQUEST", body.error, {{"field", "body"}}));
    return;
  }

  std::string action_type;
  if (is_action) {
    std::vector<std::string> declared_types;
    for (const auto& type : kActionTypes)
      if (ctx_.registry.declared(type.capability)) declared_types.emplace_back(type.type);
    if (!body.value.is_object() || !body.value.contains("type") || !body.value["type"].is_string()) {
      reply(error(400, "BAD_REQUEST", "body needs a string \"type\"", {{"field", "type"}, {"allowed", declared_types}}));
      return;
    }
    action_type = body.value["type"].get<std::string>();
    for (const auto& type : kActionTypes)
      if (type.type == action_type) capability = type.capability;
    if (capability.empty()) {
      reply(error(400, "BAD_REQUEST", "unknown action type '" + bounded_text(action_type) + "'",
                  {{"field", "type"}, {"allowed", declared_types}}));
      return;
    }
  }

  const bool audited = request.method != "GET" && request.method != "HEAD";
  const std::string event = request.method + " " + request.path + (action_type.empty() ? "" : " " + action_type);
  auto refuse = [&](http::Response response, std::string_view outcome, const std::string& why) {
    if (audited) {
      const auto seq = ctx_.audit.record({0, caller.principal, ctx_.registry.identity().ruri, caller.message_id, event,
                                          ctx_.clock.wall_ms(), "pending", {}});
      ctx_.audit.finish(seq, std::string(outcome), why);
    }
    reply(std::move(response));
  };

  // §9.1: an undeclared capability reaches no plugin.
  if (!ctx_.registry.declared(capability)) {
    refuse(error(404, "CAPABILITY_NOT_FOUND", "this robot does not declare the '" + bounded_text(capability) + "' capability",
                 {{"capability", bounded_text(capability)}, {"capabilities", ctx_.registry.names()}}),
           "blocked", "capability not declared");
    return;
  }
  CapabilityInstance* instance = ctx_.runtime.capability(capability);
  if (instance == nullptr || instance->health.failed() || !instance->object) {
    const std::string why = instance ? instance->health.reason() : "not running";
    refuse(error(503, "UNAVAILABLE", "capability '" + capability + "' is out of service: " + why, {{"capability", capability}}),
           "error", why);
    return;
  }

  const sdk::Route* route = nullptr;
  std::vector<std::string> route_methods;
  for (const auto& candidate : instance->routes) {
    const bool path_matches = is_action   ? candidate.path == kActionPath && candidate.action_type == action_type
                              : is_custom ? candidate.path == subpath
                                          : candidate.path == request.path;
    if (!path_matches) continue;
    route_methods.push_back(candidate.method);
    if (candidate.method == request.method) route = &candidate;
  }
  if (route == nullptr) {
    if (!route_methods.empty())
      refuse(error(405, "METHOD_NOT_ALLOWED", bounded_text(request.method) + " is not allowed on " + bounded_text(request.path),
                   {{"allowed", route_methods}}),
             "blocked", "method not allowed");
    else
      refuse(error(404, "NOT_FOUND", "capability '" + capability + "' has no endpoint " + bounded_text(request.path)), "blocked",
             "no such route");
    return;
  }
  const Scope route_scope = stricter(route->scope, base_scope);
  if (route_scope != base_scope && !authorize(route_scope)) return;

  if (route->motion && ctx_.estop.latched()) {
    refuse(error(423, "ESTOP_ACTIVE", "e-stop is latched; clear it with POST /api/estop/clear"), "blocked", "e-stop active");
    return;
  }
  handle_capability(*instance, *route, request, std::move(body.value), caller, reply);
}

void Api::handle_capability(CapabilityInstance& instance, const sdk::Route& route, http::Request& request, json body,
                            const Caller& caller, http::Respond respond) {
  const bool audited = request.method != "GET" && request.method != "HEAD";
  std::uint64_t seq = 0;
  if (audited) {
    const std::string type = body.is_object() && body.contains("type") && body["type"].is_string() ? " " + body["type"].get<std::string>() : "";
    seq = ctx_.audit.record({0, caller.principal, ctx_.registry.identity().ruri, caller.message_id,
                             request.method + " " + request.path + type, ctx_.clock.wall_ms(), "pending", {}});
  }

  auto sdk_request = std::make_shared<sdk::Request>();
  sdk_request->method = request.method;
  sdk_request->path = request.path;
  if (request.path.rfind(kCustomPrefix, 0) == 0) {
    const auto after = request.path.find('/', kCustomPrefix.size());
    sdk_request->subpath = after == std::string::npos ? "" : request.path.substr(after);
  }
  sdk_request->query = request.query;
  sdk_request->body = std::move(body);
  sdk_request->principal = caller.principal;
  sdk_request->role = caller.role;
  sdk_request->message_id = caller.message_id;

  // Whichever comes first — the handler's answer or the timeout — answers; the other does nothing.
  struct Pending {
    std::atomic<bool> answered{false};
    sdk::TimerId timer = 0;
  };
  auto pending = std::make_shared<Pending>();
  auto finish = [this, seq, audited, pending, respond](http::Response response, std::string outcome, std::string detail) mutable {
    if (pending->answered.exchange(true)) return;
    if (audited) ctx_.audit.finish(seq, std::move(outcome), std::move(detail));
    respond(std::move(response));
  };

  const std::string& who = instance.who;
  CapabilityInstance* target = &instance;
  pending->timer = ctx_.timers.schedule(ctx_.handler_timeout, [finish, target, timeout = ctx_.handler_timeout]() mutable {
    const std::string why = "handler did not answer within " + std::to_string(timeout.count()) + " ms";
    target->health.mark_failed(why);
    logger("kernel.api")->error("capability {}: {}; marked failed", target->name, why);
    finish(error(503, "UNAVAILABLE", "capability '" + target->name + "' " + why), "error", why);
  });
  instance.handler_worker->post([this, finish, target, who, handler = route.handler, sdk_request, pending]() mutable {
    if (pending->answered.load()) return;  // timed out while queued
    std::string failure;
    auto answer = guarded_result(who, "request handler", failure, [&] { return handler(*sdk_request); });
    ctx_.timers.cancel(pending->timer);
    if (!answer) {
      target->health.mark_failed("request handler threw: " + failure);
      finish(error(500, "INTERNAL", "capability '" + target->name + "' failed while handling the request; it is now out of service"),
             "error", failure);
      return;
    }
    const std::string outcome = answer->status < 300 ? "ok" : answer->status == 423 ? "blocked" : "error";
    std::string detail;
    if (answer->status >= 300 && answer->body.is_object() && answer->body.contains("code") && answer->body["code"].is_string())
      detail = answer->body["code"].get<std::string>();
    finish(from_plugin(*answer), outcome, detail);
  });
}

void Api::handle_kernel(const std::string& endpoint, http::Request& request, const Caller& caller, http::Respond& respond) {
  const auto record = [&](const std::string& event) {
    return ctx_.audit.record({0, caller.principal, ctx_.registry.identity().ruri, caller.message_id, event,
                              ctx_.clock.wall_ms(), "pending", {}});
  };
  if (endpoint == "/api/stop") {
    // On the kernel's steady clock (the sim drive's timeline clock), so a test can compare it with the halt events.
    const std::int64_t received_us = ctx_.clock.now_us();
    // The stop never fails on its body: a malformed body still stops the robot.
    std::string reason = "POST /api/stop";
    if (auto body = parse_json_body(request.body); body.error.empty() && body.value.is_object() &&
                                                   body.value.contains("reason") && body.value["reason"].is_string())
      reason = bounded_text(body.value["reason"].get<std::string>());  // never cut inside a UTF-8 character
    const auto seq = record("POST /api/stop");
    const auto report = ctx_.estop.latch(reason, caller.principal);
    json drivers = json::array();
    bool all_halted = true;
    for (const auto& halt : report.drivers) {
      json entry{{"id", halt.id}, {"halted", halt.halted}, {"latency_us", halt.latency_us}, {"state", halt.state}};
      if (!halt.error.empty()) entry["error"] = halt.error;  // the slow or failing driver, named
      drivers.push_back(std::move(entry));
      all_halted = all_halted && halt.halted;
    }
    ctx_.audit.finish(seq, "ok");
    respond(json_response(200, {{"status", "stopped"},
                                {"estopped", true},
                                {"motors_stopped", all_halted},
                                {"drivers", drivers},
                                {"latency_us", report.latency_us},
                                {"received_us", received_us}}));
  } else if (endpoint == "/health") {
    respond(json_response(200, {{"status", "ok"},
                                {"uptime_s", (ctx_.clock.now_us() - ctx_.started_us) / 1'000'000},
                                {"version", ctx_.version}}));
  } else if (endpoint == "/api/status") {
    respond(json_response(200, status_document()));
  } else if (endpoint == "/api/discovery") {
    respond(json_response(200, discovery_document()));
  } else if (endpoint == "/api/estop") {
    const auto state = ctx_.estop.snapshot();
    respond(json_response(200, {{"estopped", state.estopped},
                                {"since_ms", state.estopped ? json(state.since_ms) : json()},
                                {"reason", state.estopped ? json(state.reason) : json()},
                                {"source", state.estopped ? json(state.source) : json()}}));
  } else if (endpoint == "/api/estop/clear") {
    const auto seq = record("POST /api/estop/clear");
    const bool was = ctx_.estop.clear();
    ctx_.audit.finish(seq, "ok", was ? "" : "was not latched");
    respond(json_response(200, {{"status", "cleared"}, {"was_latched", was}}));
  } else if (endpoint == "/api/audit") {
    std::size_t limit = 100;
    if (auto it = request.query.find("limit"); it != request.query.end()) {
      // The whole value, digits only: "-5" (which stoul would wrap around) and "5abc" are refused, not guessed at.
      const std::string& text = it->second;
      std::size_t parsed = 0;
      const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), parsed);
      if (ec != std::errc{} || end != text.data() + text.size() || parsed == 0 || parsed > kMaxAuditLimit) {
        respond(error(400, "BAD_REQUEST", "limit must be an integer in [1, " + std::to_string(kMaxAuditLimit) + "]",
                      {{"field", "limit"}}));
        return;
      }
      limit = parsed;
    }
    respond(json_response(200, ctx_.audit.to_json(limit)));
  } else if (endpoint == "/api/plugins") {
    respond(json_response(200, {{"plugins", ctx_.host.to_json(sdk::role_grants(caller.role, Scope::Config))}}));
  }
}

bool Api::nav_running() const {
  const auto* nav = ctx_.runtime.capability("nav");
  if (nav == nullptr || !nav->object || nav->health.failed()) return false;
  auto status = ctx_.runtime.status_of(*nav);
  return status && is_true(*status, "running");
}

std::string Api::robot_state(bool nav_running) const {
  if (ctx_.estop.latched()) return "estop";
  for (const auto& instance : ctx_.runtime.capabilities())
    if (instance.health.failed()) return "error";
  for (const auto& driver : ctx_.runtime.drivers())
    if (driver.health.failed()) return "error";
  return nav_running ? "running" : "idle";
}

std::string Api::robot_state() const { return robot_state(nav_running()); }

json Api::discovery_document() const {
  return ctx_.registry.advertise(robot_state(), ctx_.port.load()).discover;
}

json Api::status_document() const {
  json doc = static_status_;
  json capabilities = json::object();
  bool nav_is_running = false;
  auto statuses = ctx_.runtime.capability_statuses();  // first: a status() that hangs fails its capability
  std::size_t i = 0;
  for (const auto& instance : ctx_.runtime.capabilities()) {
    auto& status = statuses[i++];
    json item{{"plugin", instance.plugin_id}, {"state", instance.health.failed() ? "failed" : "ok"}};
    if (instance.health.failed()) item["reason"] = instance.health.reason();
    if (status && !instance.health.failed()) {
      if (instance.name == "nav" && status->is_object()) {
        nav_is_running = is_true(*status, "running");
        if (status->contains("pose")) doc["pose"] = (*status)["pose"];  // the dead-reckoned pose, top level too
      }
      item["status"] = std::move(*status);
    }
    capabilities[instance.name] = std::move(item);
  }
  json drivers = json::array();
  for (const auto& driver : ctx_.runtime.drivers()) {
    json item{{"id", driver.id}, {"protocol", driver.protocol}, {"plugin", driver.plugin_id},
              {"actuates", driver.actuates}, {"state", driver.health.failed() ? "failed" : "ok"}};
    if (driver.health.failed()) item["reason"] = driver.health.reason();
    drivers.push_back(std::move(item));
  }
  doc["state"] = robot_state(nav_is_running);
  doc["estopped"] = ctx_.estop.latched();
  doc["uptime_s"] = (ctx_.clock.now_us() - ctx_.started_us) / 1'000'000;
  doc["drivers"] = std::move(drivers);
  doc["capabilities"] = std::move(capabilities);
  doc["nav_running"] = nav_is_running;
  return doc;
}

// ---- §15 swarm (docs/protocol.md §9) ----

namespace {

// Per-peer deadlines: a stop must finish inside 500 ms overall even with dead peers (§15.5); a command may take as
// long as a capability handler may.
constexpr std::chrono::milliseconds kStopPeerTimeout{300};

bool header_true(const http::Request& request, std::string_view name) {
  const auto value = request.header(name);
  if (!value) return false;
  std::string lower(*value);
  for (char& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return lower == "true" || lower == "1";
}

// "nodes"/"tags" of a broadcast body: a string or an array of strings.
std::optional<std::string> read_selection(const json& body, const char* key, std::vector<std::string>& out) {
  if (!body.is_object() || !body.contains(key) || body[key].is_null()) return std::nullopt;
  const json& value = body[key];
  if (value.is_string()) {
    out.push_back(value.get<std::string>());
    return std::nullopt;
  }
  if (!value.is_array()) return std::string(key) + " must be a string or an array of strings";
  for (const auto& item : value) {
    if (!item.is_string()) return std::string(key) + " must contain only strings";
    out.push_back(item.get<std::string>());
  }
  return std::nullopt;
}

}  // namespace

bool Api::is_self(const swarm::SwarmNode& node) const {
  if (node.port != ctx_.port.load()) return false;
  boost::system::error_code ec;
  const auto listen = boost::asio::ip::make_address(ctx_.config.runtime.listen_address, ec);
  if (ec) return false;
  for (const std::string& candidate : {node.host, node.ip.value_or("")}) {
    if (candidate == "localhost" && (listen.is_loopback() || listen.is_unspecified())) return true;
    const auto address = boost::asio::ip::make_address(candidate, ec);
    if (ec) continue;
    if (address == listen || (address.is_loopback() && (listen.is_loopback() || listen.is_unspecified()))) return true;
  }
  return false;
}

bool Api::handle_swarm(http::Request& request, const Caller& caller, const std::function<bool(Scope)>& authorize,
                       const http::Respond& reply) {
  const bool is_stop = request.path == "/api/stop";
  const Scope scope = is_stop ? Scope::Status : stricter(Scope::Control, CapabilityRegistry::minimum_scope("chat"));
  const std::string& ruri = ctx_.registry.identity().ruri;

  if (request.header("x-swarm-forwarded")) {
    // Forwarded by a peer: it runs here only and is never forwarded again. A stop runs as any stop; a command on a
    // node in e-stop is acknowledged and not executed (§15.5: the e-stop is always local).
    // Every node checks the broadcast's scope (control for a command) itself, before anything else.
    if (is_stop) return false;
    if (!authorize(scope)) return true;
    if (!ctx_.estop.latched()) return false;
    const auto seq = ctx_.audit.record({0, caller.principal, ruri, caller.message_id, "POST /api/command (swarm-forwarded)",
                                        ctx_.clock.wall_ms(), "pending", {}});
    ctx_.audit.finish(seq, "blocked", "e-stop active: acknowledged, not executed");
    reply(json_response(200, {{"ack", true}, {"executed", false}, {"reason", "estop_active"}}));
    return true;
  }

  JsonBody body = parse_json_body(request.body);
  const bool body_ok = body.error.empty() && body.value.is_object();
  const bool broadcast = header_true(request, "x-swarm-broadcast") ||
                         (body_ok && body.value.contains("broadcast") && body.value["broadcast"] == true);
  if (!broadcast) return false;
  if (!is_stop && !body.error.empty()) return false;  // the normal path answers 400 naming the body
  if (!authorize(scope)) return true;  // a broadcast needs the underlying command's scope, here and on each peer

  // The local stop happens first, inline, before anything is forwarded.
  http::Response local_stop;
  if (is_stop) {
    http::Respond capture = [&local_stop](http::Response response) { local_stop = std::move(response); };
    handle_kernel("/api/stop", request, caller, capture);
  }

  swarm::Selection selection;
  std::optional<std::string> bad = body_ok ? read_selection(body.value, "nodes", selection.names) : std::nullopt;
  std::string bad_field = "nodes";
  if (!bad && body_ok && (bad = read_selection(body.value, "tags", selection.tags))) bad_field = "tags";
  std::vector<swarm::SwarmNode> peers;
  if (!bad) {
    static const swarm::SwarmRegistry kNoPeers;
    const swarm::SwarmRegistry* registry = ctx_.swarm.load();
    auto chosen = swarm::select_nodes(registry ? *registry : kNoPeers, selection);
    if (auto* failure = std::get_if<swarm::SelectionError>(&chosen)) {
      bad = failure->message;
      bad_field = failure->field;
    } else {
      for (auto& node : std::get<std::vector<swarm::SwarmNode>>(chosen))
        if (!is_self(node)) peers.push_back(std::move(node));
    }
  }
  if (bad) {
    json extra{{"field", bad_field}};
    if (is_stop) extra["estopped"] = true;  // the local stop already happened
    const swarm::SwarmRegistry* registry = ctx_.swarm.load();
    extra["known_nodes"] = registry ? registry->names() : std::vector<std::string>{};
    reply(error(400, "BAD_REQUEST", *bad, std::move(extra)));
    return true;
  }

  // What the peers receive: the same command minus the broadcast fields, with their own token.
  json forwarded_body = body_ok ? body.value : json::object();
  for (const char* key : {"broadcast", "nodes", "tags"}) forwarded_body.erase(key);
  if (is_stop && !forwarded_body.contains("reason")) forwarded_body["reason"] = "swarm broadcast from " + ruri;
  std::vector<swarm::PeerRequest> requests;
  for (const auto& node : peers) {
    auto peer = swarm::peer_request(node, "POST", request.path, forwarded_body.dump());
    if (is_stop) peer.body_limit = swarm::kStopAnswerLimit;
    peer.headers.emplace_back("X-Swarm-Forwarded", ruri);
    peer.headers.emplace_back("X-Message-Id", caller.message_id);
    requests.push_back(std::move(peer));
  }

  const std::string event = "swarm broadcast POST " + request.path;
  const auto seq = ctx_.audit.record({0, caller.principal, ruri, caller.message_id, event, ctx_.clock.wall_ms(), "pending", {}});
  const auto timeout = is_stop ? kStopPeerTimeout : ctx_.handler_timeout + std::chrono::milliseconds(2000);
  const std::string local_name = ctx_.registry.identity().name;

  // Both halves (the local run and the fan-out) report here; whichever finishes last answers.
  struct Gather {
    std::mutex mutex;
    std::optional<json> local;
    std::optional<std::vector<swarm::PeerResult>> remote;
    json stop_fields;
  };
  auto gather = std::make_shared<Gather>();
  auto complete = [this, gather, seq, reply]() {
    json local;
    std::vector<swarm::PeerResult> remote;
    {
      std::lock_guard lock(gather->mutex);
      if (!gather->local || !gather->remote) return;
      local = std::move(*gather->local);
      remote = std::move(*gather->remote);
      gather->remote.reset();
      gather->local.reset();
    }
    std::vector<json> nodes{std::move(local)};
    for (const auto& result : remote)
      nodes.push_back(swarm::node_entry(result, gather->stop_fields.is_object() ? swarm::BroadcastKind::Stop
                                                                                 : swarm::BroadcastKind::Command));
    json doc = swarm::broadcast_document(std::move(nodes));
    const auto& summary = doc["summary"];
    ctx_.audit.finish(seq, summary["failed"] == 0 ? "ok" : "error",
                      summary["ok"].dump() + "/" + summary["total"].dump() + " nodes ok");
    if (gather->stop_fields.is_object()) doc.update(gather->stop_fields);  // the local stop's own fields stay on top
    http::Respond answer = reply;
    answer(json_response(200, doc));
  };

  if (is_stop) {
    json local_doc = json::parse(local_stop.body, nullptr, false);
    if (!local_doc.is_object()) local_doc = json::object();
    const bool stopped = is_true(local_doc, "motors_stopped");
    gather->stop_fields = local_doc;
    gather->local = json{{"name", local_name},
                         {"address", "local"},
                         {"local", true},
                         {"ok", stopped},
                         {"http_status", local_stop.status},
                         {"executed", true},
                         {"motors_stopped", stopped},
                         {"latency_ms", local_doc.value("latency_us", 0.0) / 1000.0},
                         {"error", stopped ? json() : json("not every driver confirmed the halt")}};
  } else {
    // The local run goes through the normal path, marked as forwarded so it is not broadcast again and the
    // e-stop acknowledgement applies here too.
    http::Request local = request;
    local.headers.erase("x-swarm-broadcast");
    local.headers["x-swarm-forwarded"] = ruri;
    local.headers["x-message-id"] = caller.message_id;
    local.body = forwarded_body.dump();
    const auto started = std::chrono::steady_clock::now();
    handle(std::move(local), [gather, complete, local_name, started](http::Response response) {
      swarm::PeerResult result;
      result.name = local_name;
      result.address = "local";
      result.reachable = true;
      result.status = response.status;
      result.body = std::move(response.body);
      result.latency_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - started).count();
      json entry = swarm::node_entry(result, swarm::BroadcastKind::Command);
      entry["local"] = true;
      {
        std::lock_guard lock(gather->mutex);
        gather->local = std::move(entry);
      }
      complete();
    });
  }

  auto remote_done = [gather, complete](std::vector<swarm::PeerResult> results) {
    {
      std::lock_guard lock(gather->mutex);
      gather->remote = std::move(results);
    }
    complete();
  };
  if (ctx_.fan_out && !requests.empty()) ctx_.fan_out->run(std::move(requests), timeout, std::move(remote_done));
  else remote_done({});
  return true;
}

}  // namespace rcand::kernel
