// The route table and the middleware, without sockets: matching (exact, prefix, fall-through, 404/405), wraps, and
// Api's order — rate limit, authentication for the row's scope, the audit entry, the e-stop pre-check.
#include <doctest/doctest.h>

#include <optional>

#include "kernel/api/api.hpp"
#include "kernel/api/router.hpp"
#include "libs/base/steady_clock.hpp"
#include "libs/rcan/crypto.hpp"

using namespace rcand;
using namespace rcand::kernel;
using sdk::Scope;

namespace {

RouteHandler named(std::string name) {
  return [name](Call&, Reply reply) {
    http::Response response;
    response.body = name;
    reply(std::move(response));
  };
}

struct Answer {
  std::optional<http::Response> response;
  Reply reply() {
    return [this](http::Response r) { response = std::move(r); };
  }
};

std::string serve(const Router& router, std::string method, std::string path) {
  const auto match = router.match(method, path);
  if (!match.route) return match.allowed.empty() ? "404" : "405";
  Call call;
  call.request.method = method;
  call.request.path = path;
  Answer answer;
  match.route->handler(call, answer.reply());
  return answer.response->body;
}

}  // namespace

TEST_CASE("router: exact rows beat prefixes, the longest prefix wins, and a missing method falls through") {
  Router router;
  router.add({"GET", "/api/estop"}, named("estop"));
  router.add({"GET", "/api/nav/status"}, named("nav status"));
  router.add({"GET", "/api/nav/*"}, named("nav read fallback"));
  router.add({"*", "/api/nav/*"}, named("nav fallback"));
  router.add({"GET", "/api/nav/deep/*"}, named("deep"));
  CHECK(serve(router, "GET", "/api/estop") == "estop");
  CHECK(serve(router, "GET", "/api/nav/status") == "nav status");
  CHECK(serve(router, "POST", "/api/nav/status") == "nav fallback");  // after authentication, in the capability
  CHECK(serve(router, "GET", "/api/nav/other") == "nav read fallback");
  CHECK(serve(router, "GET", "/api/nav/deep/x") == "deep");
  CHECK(serve(router, "GET", "/api/nav/") == "404");  // a prefix needs something after it
  CHECK(serve(router, "GET", "/nothing") == "404");
  CHECK(serve(router, "POST", "/api/estop") == "405");
  CHECK(router.match("POST", "/api/estop").allowed == std::vector<std::string>{"GET"});
  CHECK_THROWS_AS(router.add({"GET", "/api/estop"}, named("again")), std::logic_error);
}

TEST_CASE("router: a wrap runs for its method only, before the row's handler, and needs the row") {
  Router router;
  router.add({"*", "/api/command"}, named("command"));
  std::vector<std::string> seen;
  router.wrap("POST", "/api/command", [&](Call& call, Reply reply, const RouteHandler& next) {
    seen.push_back("wrap " + call.request.method);
    next(call, std::move(reply));
  });
  const auto* route = router.match("POST", "/api/command").route;
  REQUIRE(route != nullptr);
  REQUIRE(route->decorator);
  for (std::string method : {"POST", "GET"}) {
    Call call;
    call.request.method = method;
    Answer answer;
    route->decorator(call, answer.reply(), route->handler);
    CHECK(answer.response->body == "command");
  }
  CHECK(seen == std::vector<std::string>{"wrap POST"});
  CHECK_THROWS_AS(router.wrap("GET", "/api/none", {}), std::logic_error);
}

TEST_CASE("router: a group's rows are swapped in one snapshot; wraps survive the swap; a match keeps its snapshot") {
  Router router;
  router.add({"POST", "/api/stop"}, named("stop"));
  router.add({"*", "/api/cap/*"}, named("starting"), "capabilities");
  int wrapped = 0;
  router.wrap("POST", "/api/stop", [&](Call& call, Reply reply, const RouteHandler& next) {
    ++wrapped;
    next(call, std::move(reply));
  });
  const auto before = router.match("GET", "/api/cap/gripper/state");  // a request in flight across the swap
  REQUIRE(before.route != nullptr);

  router.replace_group("capabilities", {{RouteSpec{"GET", "/api/cap/gripper/state"}, named("gripper state")},
                                        {RouteSpec{"*", "/api/cap/*"}, named("fallback")}});
  CHECK(serve(router, "GET", "/api/cap/gripper/state") == "gripper state");
  CHECK(serve(router, "POST", "/api/cap/other/x") == "fallback");
  CHECK(serve(router, "POST", "/api/stop") == "stop");
  Call call;
  call.request.method = "POST";
  Answer answer;
  const auto stop = router.match("POST", "/api/stop");
  REQUIRE(stop.route->decorator);  // the service's wrap is on the new snapshot's row too
  stop.route->decorator(call, answer.reply(), stop.route->handler);
  CHECK(wrapped == 1);
  CHECK(answer.response->body == "stop");
  // The old snapshot is still whole for the request that matched in it.
  Answer old;
  before.route->handler(call, old.reply());
  CHECK(old.response->body == "starting");
  CHECK(before.table != router.routes());
  // A clash with another group's row changes nothing.
  CHECK_THROWS_AS(router.replace_group("capabilities", {{RouteSpec{"POST", "/api/stop"}, named("clash")}}), std::logic_error);
  CHECK(serve(router, "GET", "/api/cap/gripper/state") == "gripper state");
}

namespace {

struct ApiRig {
  SteadyClock clock;
  ActuatorTable table;
  Estop estop{clock, table};
  AuditLog audit;
  Authenticator auth{[] {
    AuthSettings settings;
    settings.tokens = {{"guest", sdk::Role::Guest, sha256_hex("guest-token")},
                       {"owner", sdk::Role::Owner, sha256_hex("owner-token")}};
    return settings;
  }()};
  config::RuntimeConfig runtime;
  std::optional<Api> api;
  int handled = 0;
  ApiRig() {
    runtime.rate_limit_principal_per_s = 1000;
    runtime.rate_limit_address_per_s = 1000;
    runtime.rate_limit_burst_s = 1;
    api.emplace(runtime, auth, audit, estop, clock);
    auto count = [this](Call& call, Reply reply) {
      ++handled;
      if (call.audit_seq != 0) audit.finish(call.audit_seq, "ok");
      reply(http::Response{});
    };
    api->router().add({"POST", "/api/move", Scope::Control, true, true}, count);
    api->router().add({"GET", "/api/read", Scope::Status}, count);
  }
  http::Response request(std::string method, std::string path, std::string token = {}) {
    http::Request request;
    request.method = std::move(method);
    request.path = request.target = std::move(path);
    request.remote = "127.0.0.1:40000";
    if (!token.empty()) request.headers["authorization"] = "Bearer " + token;
    Answer answer;
    api->handle(std::move(request), answer.reply());
    REQUIRE(answer.response.has_value());  // every row here answers inline
    return *answer.response;
  }
};

bool has_message_id(const http::Response& response) {
  for (const auto& [name, value] : response.headers)
    if (name == "X-Message-Id" && !value.empty()) return true;
  return false;
}

}  // namespace

TEST_CASE("api middleware: 404 before authentication, the row's scope, the audit entry, then the e-stop pre-check") {
  ApiRig rig;
  auto unknown = rig.request("GET", "/api/unknown");
  CHECK(unknown.status == 404);
  CHECK(has_message_id(unknown));
  CHECK(rig.request("POST", "/api/move").status == 401);
  auto forbidden = rig.request("POST", "/api/move", "guest-token");
  CHECK(forbidden.status == 403);
  CHECK(forbidden.body.find("\"required_scope\":\"control\"") != std::string::npos);
  CHECK(rig.audit.total() == 0);  // refused before the audit entry
  CHECK(rig.request("GET", "/api/read", "guest-token").status == 200);
  CHECK(rig.request("POST", "/api/move", "owner-token").status == 200);
  CHECK(rig.handled == 2);
  CHECK(rig.audit.to_json(1)["entries"][0]["event"] == "POST /api/move");
  CHECK(rig.audit.to_json(1)["entries"][0]["outcome"] == "ok");

  rig.estop.latch("test", "test");
  CHECK(rig.request("POST", "/api/move", "owner-token").status == 423);
  CHECK(rig.handled == 2);  // the handler never ran
  CHECK(rig.audit.to_json(1)["entries"][0]["outcome"] == "blocked");
  CHECK(rig.request("GET", "/api/read", "guest-token").status == 200);  // reads are not motion
}
