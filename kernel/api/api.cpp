#include "kernel/api/api.hpp"

#include <algorithm>

#include <rcand/sdk/contract/door.hpp>

#include "kernel/api/answers.hpp"
#include "libs/base/bounded_text.hpp"

namespace rcand::kernel {
namespace {

using nlohmann::json;
using sdk::Scope;

bool valid_message_id(std::string_view id) {
  if (id.empty() || id.size() > 64) return false;
  for (char c : id)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-' && c != '_' && c != '.') return false;
  return true;
}

http::Response too_many_requests(const std::string& who, double per_s, std::chrono::milliseconds wait) {
  const auto retry_after_s = std::max<std::int64_t>(1, (wait.count() + 999) / 1000);
  json limit = per_s;
  auto response =
      error_response(429, "RATE_LIMITED", "too many requests from " + who + " (limit " + limit.dump() + " per second)",
                     {{"retry_after_s", retry_after_s}});
  response.headers.emplace_back("Retry-After", std::to_string(retry_after_s));
  return response;
}

}  // namespace

// docs/protocol.md §3: ?token= only where clients cannot set headers (a browser's <img>, a WebSocket).
std::optional<std::string_view> request_credential(const http::Request& request) {
  if (auto header = request.header("authorization")) return bearer_token(*header);
  const auto token = request.query.find("token");
  if (token != request.query.end() && (request.path == "/api/stream/mjpeg" || request.path.starts_with("/ws/")))
    return token->second;
  return std::nullopt;
}

Api::Api(const config::RuntimeConfig& config, const Authenticator& auth, AuditLog& audit, const Estop& estop,
         const sdk::Clock& clock, http::OriginPolicy origins)
    : auth_(auth),
      audit_(audit),
      estop_(estop),
      clock_(clock),
      origins_(std::move(origins)),
      principal_limiter_({config.rate_limit_principal_per_s, config.rate_limit_burst_s}),
      address_limiter_({config.rate_limit_address_per_s, config.rate_limit_burst_s}) {}

void Api::log_refusal(const char* logger_name, const http::Request& request, const std::string& what) {
  const std::string address = http::client_address(request.remote);
  const auto verdict = refusal_log_.admit(address);
  if (!verdict.log) return;
  auto log = logger(logger_name);
  if (verdict.suppressed > 0)
    log->warn("{} more refusals for {} not logged (more than {} a second)", verdict.suppressed, address, kRefusalLogLines);
  log->warn("{} {} from {}: {}", bounded_text(request.method), bounded_text(request.path), request.remote, what);
}

std::optional<http::Response> Api::screen(const http::Request& request) {
  auto refusal = origins_.check(request, auth_.open_mode());  // open: a rebinding page's GETs need no credential
  if (!refusal) return std::nullopt;
  log_refusal("kernel.api", request, "403 (" + refusal->message + ")");
  return error_response(403, "ORIGIN_NOT_ALLOWED", refusal->message,
                        {{"origin", refusal->origin.empty() ? json() : json(refusal->origin)}});
}

void Api::handle(http::Request&& request, http::Respond respond) { serve(std::move(request), nullptr, std::move(respond)); }

void Api::execute_action(const Principal& principal, json body, std::function<void(int, json)> done) {
  http::Request request;
  request.method = "POST";
  request.target = request.path = "/api/action";
  request.body = body.dump(-1, ' ', false, json::error_handler_t::replace);
  request.remote = "r2r";
  request.headers["x-message-id"] = "r2r-" + std::to_string(clock_.wall_ms()) + "-" + std::to_string(++message_counter_);
  execute(principal, std::move(request), [done = std::move(done)](http::Response response) {
    json answer = json::parse(response.body, nullptr, false);
    done(response.status, answer.is_discarded() ? json::object() : std::move(answer));
  });
}

void Api::execute(const Principal& principal, http::Request request, http::Respond respond, json audit_note) {
  serve(std::move(request), &principal, std::move(respond), std::move(audit_note));
}

void Api::execute_for_caller(http::Request request, http::Respond respond, json audit_note) {
  serve(std::move(request), nullptr, std::move(respond), std::move(audit_note), /*address_limited=*/false);
}

bool Api::admit_address(const http::Request& request, const Reply& reply) {
  const std::string address = http::client_address(request.remote);
  const auto wait = address_limiter_.admit(address, clock_.now_us());
  if (!wait) return true;
  log_refusal("kernel.api", request, "address " + address + " over its rate limit (429)");
  reply(too_many_requests("address " + address, address_limiter_.limit().per_s, *wait));
  return false;
}

bool Api::admit_principal(const Call& call, const Reply& reply) {
  if (call.principal == "anonymous") return true;
  const auto wait = principal_limiter_.admit(call.principal, clock_.now_us());
  if (!wait) return true;
  log_refusal("kernel.api", call.request, "principal '" + call.principal + "' over its rate limit (429)");
  reply(too_many_requests("principal '" + call.principal + "'", principal_limiter_.limit().per_s, *wait));
  return false;
}

bool Api::authenticate(Call& call, const Principal* authenticated, Scope scope, const Reply& reply) {
  if (authenticated != nullptr) {  // an R2R peer, authenticated by the R2R node: only its scopes are checked here
    call.peer = true;
    call.principal = authenticated->name;
    call.role = authenticated->role;
    call.scopes = authenticated->scopes;
    if (call.has_scope(scope)) return true;
    reply(error_response(403, "INSUFFICIENT_PRIVILEGES",
                         "principal '" + authenticated->name + "' lacks scope '" + std::string(sdk::scope_name(scope)) + "'",
                         {{"required_scope", sdk::scope_name(scope)}}));
    return false;
  }
  auto verdict = auth_.authorize(request_credential(call.request), scope, clock_.wall_ms() / 1000);
  if (auto* failure = std::get_if<AuthError>(&verdict)) {
    log_refusal("kernel.auth", call.request, std::to_string(failure->status) + " (" + failure->message + ")");
    json extra = json::object();
    if (failure->status == 403) extra["required_scope"] = sdk::scope_name(scope);
    reply(error_response(failure->status, failure->code, failure->message, extra));
    return false;
  }
  auto& principal = std::get<Principal>(verdict);
  call.principal = std::move(principal.name);
  call.role = principal.role;
  call.scopes = std::move(principal.scopes);
  return true;
}

void Api::serve(http::Request&& request, const Principal* authenticated, http::Respond respond, json audit_note,
                bool address_limited) {
  Call call;
  call.audit_note = std::move(audit_note);
  if (auto id = request.header("x-message-id"); id && valid_message_id(*id)) call.message_id = std::string(*id);
  else call.message_id = "m-" + std::to_string(clock_.wall_ms()) + "-" + std::to_string(++message_counter_);
  call.request = std::move(request);
  // Every answer carries the message id, so a client can find its request in the audit log.
  Reply reply = [respond = std::move(respond), id = call.message_id](http::Response response) {
    response.headers.emplace_back("X-Message-Id", id);
    respond(std::move(response));
  };

  const auto match = router_.match(call.request.method, call.request.path);
  // docs/protocol.md §6.4: the e-stop paths are never rate-limited; an R2R command comes from the R2R node, which
  // bounds its peers itself.
  const bool limited = match.route == nullptr || match.route->spec.rate_limited;
  if (limited && address_limited && authenticated == nullptr && !admit_address(call.request, reply)) return;
  if (match.route == nullptr) {
    if (match.allowed.empty()) reply(error_response(404, "NOT_FOUND", "no endpoint " + bounded_text(call.request.path)));
    else
      reply(error_response(405, "METHOD_NOT_ALLOWED",
                           bounded_text(call.request.method) + " is not allowed on " + bounded_text(call.request.path),
                           {{"allowed", match.allowed}}));
    return;
  }
  const RouteSpec& spec = match.route->spec;
  if (!authenticate(call, authenticated, spec.scope, reply)) return;
  if (limited && !admit_principal(call, reply)) return;
  if (match.route->decorator) {
    match.route->decorator(call, std::move(reply), [this, table = match.table, route = match.route](Call& c, Reply r) {
      dispatch(*route, c, std::move(r));
    });
    return;
  }
  dispatch(*match.route, call, std::move(reply));
}

void Api::dispatch(const Route& route, Call& call, Reply reply) {
  const RouteSpec& spec = route.spec;
  if (spec.audited) {
    std::string event = call.request.method + " " + call.request.path;
    call.audit_seq = spec.stop ? audit_.begin_stop(call.principal, call.message_id, std::move(event), estop_.latched())
                               : audit_.begin(call.principal, call.message_id, std::move(event), call.audit_note);
  }
  // The one door's e-stop step (rcand/sdk/contract/door.hpp), as on the fake host; authentication checked the row's
  // scope. Only for motion rows: the stop lane builds nothing here.
  if (spec.motion) {
    auto verdict = sdk::contract::decide({"principal '" + call.principal + "'", call.scopes}, spec, estop_.latched());
    if (!verdict.run) {
      if (spec.audited) audit_.finish(call.audit_seq, "blocked", verdict.why);
      return reply(json_response(verdict.refusal.status, verdict.refusal.body));
    }
  }
  route.handler(call, std::move(reply));
}

}  // namespace rcand::kernel
