#include "kernel/api/capability_routes.hpp"

#include <algorithm>
#include <atomic>
#include <memory>

#include <rcand/sdk/contract/door.hpp>

#include "kernel/api/answers.hpp"
#include "kernel/api/api.hpp"
#include "kernel/auth/caller_credential.hpp"
#include "kernel/auth/slots.hpp"
#include "kernel/plugins/guarded.hpp"
#include "libs/base/bounded_text.hpp"
#include "libs/base/json_body.hpp"
#include "libs/http/response_stream.hpp"
#include "libs/http/stream_writer.hpp"

namespace rcand::kernel {
namespace {

using nlohmann::json;
using sdk::Scope;

namespace contract = sdk::contract;
using contract::kCustomPrefix;

bool is_read(std::string_view method) { return method == "GET" || method == "HEAD"; }

// docs/protocol.md §7.16: a request handler that throws fails that request (500 INTERNAL, logged by the trampoline),
// not its capability. Handlers run one at a time on the capability's worker, so the throw interrupted no other request;
// the usual cause is a body the handler did not check (json::type_error), and failing the instance would let any
// caller with the route's scope take the capability - its stop and cancel routes too - out of service until a restart.
// Hangs (the worker is stuck) and lifecycle hooks still fail the instance.
void count_handler_throw(CapabilityInstance& instance) { instance.health.count_handler_error(); }

constexpr SlotWords kStreamSlots{"streamed answers (MJPEG viewers and the like)",
                                 "",
                                 "runtime.max_streams_per_principal",
                                 "runtime.max_streams_per_address",
                                 "",
                                 "TOO_MANY_STREAMS"};

// The contract's answers (the fake host gives the same ones) as HTTP responses.
http::Response answer(const sdk::Response& response) { return json_response(response.status, response.body); }

// A dispatched request is answered once: by its handler (or stream writer), or by the timeout, whichever is first.
struct Pending {
  std::atomic<bool> answered{false}, returned{false};  // returned: the handler itself came back
  sdk::TimerId timer = 0;
};
using Finish = std::function<bool(http::Response, std::string outcome, std::string detail)>;

std::shared_ptr<sdk::Request> make_request(const Call& call, json body) {
  auto request = std::make_shared<sdk::Request>();
  request->method = call.request.method;
  request->path = call.request.path;
  if (call.request.path.starts_with(kCustomPrefix)) {
    const auto after = call.request.path.find('/', kCustomPrefix.size());
    request->subpath = after == std::string::npos ? "" : call.request.path.substr(after);
  }
  request->query = call.request.query;
  request->body = std::move(body);
  request->principal = call.principal;
  request->role = call.role;
  request->message_id = call.message_id;
  request->scopes = call.scopes;
  // For a plugin that acts on this caller's behalf later (RequestDispatcher authorizes the caller again from it).
  if (!call.peer) request->credential = std::make_shared<const CallerCredential>(request_credential(call.request));
  return request;
}

class CapabilityRoutes {
 public:
  explicit CapabilityRoutes(const CapabilityRouteDeps& deps) : d_(deps) {}

  // Answers with `response`, finishing the call's audit entry (if any) as `outcome`.
  void refuse(Call& call, const Reply& reply, http::Response response, std::string_view outcome, const std::string& why) const {
    if (call.audit_seq != 0) d_.audit.finish(call.audit_seq, std::string(outcome), why);
    reply(std::move(response));
  }

  // The instance serving `name`, admitted through its reload gate (`pass`, held until the handler returns), or
  // answers 404/503 and returns null.
  CapabilityInstance* available(const std::string& name, Call& call, const Reply& reply, ReloadGate::Pass& pass) const {
    if (!d_.registry.declared(name)) {  // §9.1: an undeclared capability reaches no plugin
      refuse(call, reply, answer(contract::not_declared(bounded_text(name), d_.registry.names())), "blocked",
             "capability not declared");
      return nullptr;
    }
    CapabilityInstance* instance = d_.runtime.capability(name);
    if (instance != nullptr && instance->starting.load()) {  // nothing of it may be read until it is up
      refuse(call, reply, answer(contract::starting(name)), "error", "starting");
      return nullptr;
    }
    if (instance != nullptr && !(pass = instance->gate->enter())) {
      refuse(call, reply, answer(contract::out_of_service(name, "its plugin is being reloaded")), "error", "plugin reloading");
      return nullptr;
    }
    if (instance == nullptr || instance->health.failed() || !instance->object) {
      const std::string why = instance ? instance->health.reason() : "not running";
      refuse(call, reply, answer(contract::out_of_service(name, why)), "error", why);
      return nullptr;
    }
    return instance;
  }

  // A routed request: the body parsed, then the handler on the capability's worker. The route is looked up by its
  // method and path at each call: a reloaded plugin's routes replace the ones it had.
  void serve(const std::string& name, const std::string& method, const std::string& path, Call& call, const Reply& reply) const {
    ReloadGate::Pass pass;
    CapabilityInstance* instance = available(name, call, reply, pass);
    if (instance == nullptr) return;
    const auto route = std::find_if(instance->routes.begin(), instance->routes.end(), [&](const sdk::Route& r) {
      return r.action_type.empty() && r.method == method && r.path == path;
    });
    if (route == instance->routes.end()) return unrouted(name, call, reply);
    JsonBody body = parse_json_body(call.request.body);
    if (!body.error.empty())
      return refuse(call, reply, error_response(400, "BAD_REQUEST", body.error, {{"field", "body"}}), "blocked", "bad body");
    dispatch(*instance, *route, call, std::move(body.value), reply, std::move(pass));
  }

  // A stream route: the handler gets a writer whose first answer (a stream, a body, or JSON) ends the timeout.
  void serve_stream(const std::string& name, const std::string& method, const std::string& path, Call& call,
                    const Reply& reply) const {
    ReloadGate::Pass pass;
    CapabilityInstance* instance = available(name, call, reply, pass);
    if (instance == nullptr) return;
    const auto route = std::find_if(instance->stream_routes.begin(), instance->stream_routes.end(),
                                    [&](const sdk::StreamRoute& r) { return r.method == method && r.path == path; });
    if (route == instance->stream_routes.end()) return unrouted(name, call, reply);
    JsonBody body = parse_json_body(call.request.body);
    if (!body.error.empty())
      return refuse(call, reply, error_response(400, "BAD_REQUEST", body.error, {{"field", "body"}}), "blocked", "bad body");
    auto request = make_request(call, std::move(body.value));
    auto pending = std::make_shared<Pending>();
    Finish finish = arm(*instance, call, reply, pending);
    auto holder = slot_holder(call.principal, call.role, d_.auth.open_mode(), http::client_address(call.request.remote));
    auto writer = http::make_stream_writer(
        [finish, timers = &d_.timers, pending, streams = &d_.streams, holder, role = call.role](http::Response response) {
          if (response.stream) {  // a multipart stream holds a slot while it runs; over a cap it is refused instead
            auto claim = streams->claim(holder);
            if (!claim.slot) {
              response.stream->close();
              if (finish(slot_refusal(claim, kStreamSlots, holder, role), "blocked", "TOO_MANY_STREAMS"))
                timers->cancel(pending->timer);
              return false;
            }
            response.stream->hold(std::move(claim.slot));
          }
          const int status = response.status;
          std::string detail;  // as for JSON routes: the error body's code, else the status
          if (status >= 300) {
            const json error = response.content_type == "application/json" ? json::parse(response.body, nullptr, false) : json();
            detail = error.is_object() && error.contains("code") && error["code"].is_string() ? error["code"].get<std::string>()
                                                                                              : std::to_string(status);
          }
          const char* outcome = status < 300 ? "ok" : status == 423 ? "blocked" : "error";
          if (!finish(std::move(response), outcome, detail)) return false;
          timers->cancel(pending->timer);
          return true;
        });
    instance->handler_worker->post(
        [finish, target = instance, handler = route->handler, request, pending, writer, pass = std::move(pass)]() mutable {
          if (pending->answered.load()) return;  // timed out while queued
          std::string failure;
          // The handler gets a copy: ours outlives a throw, so the 500 below answers before a dropped writer's would.
          const bool ok = guarded_call(target->who, "stream handler", failure, [&] { handler(*request, writer); });
          pending->returned = true;
          if (ok) return;
          count_handler_throw(*target);
          finish(answer(contract::handler_threw(target->name)), "error", bounded_text(failure));
        });
  }

  // The one door (rcand/sdk/contract/door.hpp) for a route found after matching: its scope, then the e-stop.
  bool admitted(Call& call, const Reply& reply, const contract::RouteRow& row) const {
    auto verdict = contract::decide({"principal '" + call.principal + "'", call.scopes}, row, d_.estop.latched());
    if (!verdict.run) refuse(call, reply, answer(verdict.refusal), "blocked", verdict.why);
    return verdict.run;
  }

  // What an Unserved row answers: not declared, out of service, or no route.
  void unrouted(const std::string& owner, Call& call, const Reply& reply) const {
    const std::string& path = call.request.path;
    std::string subpath;
    const std::string name = contract::unserved_capability(owner, path, &subpath);
    const bool custom = path.starts_with(kCustomPrefix);
    if (custom && find_standard_capability(name) != nullptr)  // standard ones have their own endpoints
      return refuse(
          call, reply,
          error_response(404, "NOT_FOUND", "'" + bounded_text(name) + "' is a standard capability; use its standard endpoint"),
          "blocked", "standard capability under /api/cap");
    ReloadGate::Pass pass;
    CapabilityInstance* instance = available(name, call, reply, pass);
    if (instance == nullptr) return;
    // A route the table has no row for: one a reloaded plugin added, or one of a plugin that failed at startup.
    const auto added = std::find_if(instance->routes.begin(), instance->routes.end(), [&](const sdk::Route& r) {
      return r.action_type.empty() && r.method == call.request.method && r.path == (custom ? subpath : path);
    });
    if (added != instance->routes.end()) {
      if (!admitted(call, reply, contract::live_row(name, added->method, added->scope, added->motion))) return;
      JsonBody body = parse_json_body(call.request.body);
      if (!body.error.empty())
        return refuse(call, reply, error_response(400, "BAD_REQUEST", body.error, {{"field", "body"}}), "blocked", "bad body");
      return dispatch(*instance, *added, call, std::move(body.value), reply, std::move(pass));
    }
    std::vector<std::string> methods;
    for (const auto& route : instance->routes)
      if (route.action_type.empty() && route.path == (custom ? subpath : path)) methods.push_back(route.method);
    for (const auto& route : instance->stream_routes)
      if (route.path == (custom ? subpath : path)) methods.push_back(route.method);
    const char* why = methods.empty() ? "no such route" : "method not allowed";
    refuse(call, reply, answer(contract::no_route(name, bounded_text(call.request.method), bounded_text(path), methods)),
           "blocked", why);
  }

  // POST /api/action: the body's "type" picks its own row of the table.
  void action(Call& call, const Reply& reply) const {
    JsonBody body = parse_json_body(call.request.body);
    if (!body.error.empty()) return reply(error_response(400, "BAD_REQUEST", body.error, {{"field", "body"}}));
    std::vector<std::string> declared_types;
    for (const auto& cap : standard_capabilities())
      if (d_.registry.declared(cap.name))
        for (auto type : cap.action_types) declared_types.emplace_back(type);
    sdk::Response refusal;
    const std::string type = contract::action_type_of(body.value, declared_types, refusal);
    if (refusal.status != 200) return reply(answer(refusal));
    const contract::RouteRow* row = contract::match(table_, "POST", contract::kActionPath, type).row;
    call.audit_seq = d_.audit.begin(call.principal, call.message_id, "POST /api/action " + type, call.audit_note);
    ReloadGate::Pass pass;
    CapabilityInstance* instance = available(row->capability, call, reply, pass);
    if (instance == nullptr) return;
    const auto route = std::find_if(instance->routes.begin(), instance->routes.end(), [&](const sdk::Route& r) {
      return r.path == contract::kActionPath && r.action_type == type && r.method == "POST";
    });
    if (route == instance->routes.end())
      return refuse(call, reply, answer(contract::no_endpoint(instance->name, std::string(contract::kActionPath))), "blocked",
                    "no such route");
    if (!admitted(call, reply, contract::live_row(instance->name, "POST", route->scope, route->motion))) return;
    dispatch(*instance, *route, call, std::move(body.value), reply, std::move(pass));
  }

  std::vector<contract::RouteRow> table_;  // set once at startup, before serving
  void dispatch(CapabilityInstance& instance, const sdk::Route& route, Call& call, json body, const Reply& reply,
                ReloadGate::Pass pass) const;
  // The once-only answer of a dispatched request, and its timeout: a handler still running then fails its
  // capability; one that returned without answering (a stream never started) only gets the client a 503.
  Finish arm(CapabilityInstance& instance, const Call& call, const Reply& reply, const std::shared_ptr<Pending>& pending) const;

 private:
  const CapabilityRouteDeps& d_;
};

Finish CapabilityRoutes::arm(CapabilityInstance& instance, const Call& call, const Reply& reply,
                             const std::shared_ptr<Pending>& pending) const {
  Finish finish = [audit = &d_.audit, seq = call.audit_seq, pending, reply](http::Response response, std::string outcome,
                                                                            std::string detail) {
    if (pending->answered.exchange(true)) return false;
    if (seq != 0) audit->finish(seq, std::move(outcome), std::move(detail));
    reply(std::move(response));
    return true;
  };
  CapabilityInstance* target = &instance;
  pending->timer = d_.timers.schedule(d_.handler_timeout, [finish, target, pending, timeout = d_.handler_timeout] {
    const bool hung = !pending->returned.load();
    const std::string why = std::string(hung ? "handler did not answer" : "stream handler did not start its answer") +
                            " within " + std::to_string(timeout.count()) + " ms";
    if (hung && !pending->answered.load()) {
      target->health.mark_failed(why);
      logger("kernel.api")->error("capability {}: {}; marked failed", target->name, why);
    }
    finish(error_response(503, "UNAVAILABLE", "capability '" + target->name + "' " + why), "error", why);
  });
  return finish;
}

void CapabilityRoutes::dispatch(CapabilityInstance& instance, const sdk::Route& route, Call& call, json body, const Reply& reply,
                                ReloadGate::Pass pass) const {
  auto request = make_request(call, std::move(body));
  auto pending = std::make_shared<Pending>();
  Finish finish = arm(instance, call, reply, pending);
  instance.handler_worker->post([timers = &d_.timers, finish, target = &instance, handler = route.handler, request, pending,
                                 pass = std::move(pass)] {
    if (pending->answered.load()) return;  // timed out while queued
    std::string failure;
    auto result = guarded_result(target->who, "request handler", failure, [&] { return handler(*request); });
    pending->returned = true;
    timers->cancel(pending->timer);
    if (!result) {
      count_handler_throw(*target);
      finish(answer(contract::handler_threw(target->name)), "error", bounded_text(failure));
      return;
    }
    const std::string outcome = result->status < 300 ? "ok" : result->status == 423 ? "blocked" : "error";
    std::string detail;
    if (result->status >= 300 && result->body.is_object() && result->body.contains("code") && result->body["code"].is_string())
      detail = result->body["code"].get<std::string>();
    finish(answer(contract::normalized(*result)), outcome, detail);
  });
}

}  // namespace

json served_routes(const CapabilityInstance& instance) {
  const StandardCapability* standard = find_standard_capability(instance.name);
  json list = json::array();
  auto add = [&](const std::string& method, const std::string& path, Scope declared, bool motion, const char* kind) {
    json row{{"method", method}, {"path", path}, {"scope", sdk::scope_name(contract::route_scope(declared, method, !standard))}};
    if (motion) row["motion"] = true;
    if (kind != nullptr) row[kind] = true;
    list.push_back(std::move(row));
  };
  for (const auto& route : instance.routes) {
    if (!route.action_type.empty()) {  // POST /api/action, picked by the body's type
      add(route.method, route.path, route.scope, route.motion, nullptr);
      list.back()["type"] = route.action_type;
    } else if (const std::string path = contract::served_path(instance.name, route.path);
               contract::within_mounts(standard, path)) {
      add(route.method, path, route.scope, route.motion, nullptr);
    }
  }
  for (const auto& route : instance.stream_routes)
    if (const std::string path = contract::served_path(instance.name, route.path); contract::within_mounts(standard, path))
      add(route.method, path, route.scope, false, "stream");
  return list;
}

void install_capability_routes(Router& router, const CapabilityRouteDeps& deps) {
  std::vector<contract::RunningCapability> running;
  for (const auto& instance : deps.runtime.capabilities()) {
    if (instance.starting.load() || !instance.object || instance.health.failed()) continue;
    auto& cap = running.emplace_back(contract::RunningCapability{instance.name, {}});
    for (const auto& r : instance.routes) cap.routes.push_back({r.method, r.path, r.action_type, r.scope, r.motion, false});
    for (const auto& r : instance.stream_routes) cap.routes.push_back({r.method, r.path, "", r.scope, false, true});
  }
  auto table = contract::route_table(running);
  for (const auto& refused : table.refused) logger("kernel.api")->warn("{}", refused);
  auto routes = std::make_shared<CapabilityRoutes>(deps);
  routes->table_ = std::move(table.rows);
  std::vector<std::pair<RouteSpec, RouteHandler>> rows;
  for (const auto& row : routes->table_) {
    if (!row.action_type.empty()) continue;  // an action type's row: POST /api/action picks it by the body's type
    RouteHandler handler = [routes = std::shared_ptr<const CapabilityRoutes>(routes), row](Call& call, Reply reply) {
      switch (row.kind) {
        case contract::RowKind::Route: return routes->serve(row.capability, row.method, row.route_path, call, reply);
        case contract::RowKind::Stream: return routes->serve_stream(row.capability, row.method, row.route_path, call, reply);
        case contract::RowKind::Action: return routes->action(call, reply);
        case contract::RowKind::Unserved: return routes->unrouted(row.capability, call, reply);
      }
    };
    const bool audited = row.kind != contract::RowKind::Action && !is_read(row.method);
    rows.emplace_back(RouteSpec{row.method, row.path, row.scope, audited, row.motion}, std::move(handler));
  }
  router.replace_group("capabilities", std::move(rows));
}

}  // namespace rcand::kernel
