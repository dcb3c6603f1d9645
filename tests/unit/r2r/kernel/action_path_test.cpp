// An R2R `command` runs exactly the POST /api/action path of a real kernel (embedded, no socket): the scope check,
// the e-stop 423 pre-check answered as code 105 with nothing moving, and the audit entry.
#include <doctest/doctest.h>

#include <chrono>
#include <condition_variable>
#include <mutex>
#include <set>
#include <thread>

#include "kernel/api/api.hpp"
#include "kernel/api/request_dispatch.hpp"
#include "kernel/auth/caller_credential.hpp"
#include "kernel/kernel.hpp"
#include "libs/rcan/crypto.hpp"
#include "libs/rcan/role_scopes.hpp"
#include "loopback_network.hpp"
#include "rcand/sdk/testing/manual_clock.hpp"
#include "services/r2r/r2r_node.hpp"

using namespace rcand;
using namespace rcand::kernel;
using namespace rcand::services::r2r;
using nlohmann::json;
using rcand::sdk::Role;

namespace {

const std::string kOwnerToken = "r2r-kernel-test-owner-token";
const std::string kUserToken = "r2r-kernel-test-user-token";
const std::string kGuestToken = "r2r-kernel-test-guest-token";

config::RobotConfig sim_rover() {
  const std::string yaml = R"(rcan_version: "1.3"
metadata: {robot_name: bob, robot_uuid: "5f3c2a1b", manufacturer: rcand, model: sim-rover}
physics: {type: differential, wheel_circumference_m: 0.21, turn_time_per_deg_s: 0.008}
drivers:
  - {id: drive0, protocol: sim_diff_drive}
rcan_protocol: {port: 8000, capabilities: [status, teleop], enable_mdns: false, enable_jwt: false}
runtime:
  listen: {address: 127.0.0.1, port: 0}
  plugin_paths: [")" RCAND_PLUGIN_DIR R"("]
  swarm_file: /nonexistent/swarm.yaml
  auth:
    tokens:
      - {principal: owner, role: owner, sha256: )" +
                           sha256_hex(kOwnerToken) +
                           "}\n      - {principal: chat-user, role: user, sha256: " + sha256_hex(kUserToken) +
                           "}\n      - {principal: chat-guest, role: guest, sha256: " + sha256_hex(kGuestToken) + "}\n";
  return config::parse_robot_config(yaml, "bob.rcan.yaml", "/").config;
}

// Runs the Api with `request` and waits for its answer (capability handlers answer from their worker).
http::Response call(Api& api, std::string method, std::string path, std::string body = {}) {
  http::Request request;
  request.method = std::move(method);
  request.target = request.path = std::move(path);
  request.body = std::move(body);
  request.headers["authorization"] = "Bearer " + kOwnerToken;
  request.remote = "127.0.0.1:1";
  std::mutex mutex;
  std::condition_variable cv;
  std::optional<http::Response> answer;
  api.handle(std::move(request), [&](http::Response response) {
    std::lock_guard lock(mutex);
    answer = std::move(response);
    cv.notify_all();
  });
  std::unique_lock lock(mutex);
  REQUIRE(cv.wait_for(lock, std::chrono::seconds(10), [&] { return answer.has_value(); }));
  return *answer;
}

struct Answer {
  int status = 0;
  json body;
};
Answer execute(Api& api, const Principal& who, json body) {
  std::mutex mutex;
  std::condition_variable cv;
  std::optional<Answer> answer;
  api.execute_action(who, std::move(body), [&](int status, json reply) {
    std::lock_guard lock(mutex);
    answer = Answer{status, std::move(reply)};
    cv.notify_all();
  });
  std::unique_lock lock(mutex);
  REQUIRE(cv.wait_for(lock, std::chrono::seconds(10), [&] { return answer.has_value(); }));
  return *answer;
}

// Motion on the sim drive's timeline: events that set a wheel speed other than zero (stops and halts do not count).
int drive_commands(Api& api) {
  const json doc = json::parse(call(api, "GET", "/api/drivers/drive0").body);
  int moving = 0;
  for (const auto& event : doc["status"]["timeline"])
    if (event["left"] != 0.0 || event["right"] != 0.0) ++moving;
  return moving;
}

const Principal kPeer{"peer-alex", Role::User, default_scopes(Role::User), "signature"};
const json kMove{{"type", "move"}, {"linear", 0.2}, {"angular", 0.0}, {"duration_ms", 50}};

}  // namespace

TEST_CASE("Api::execute_action: the action route as the principal; 423 while e-stopped and no motion; audited") {
  Kernel kernel(sim_rover(), embedded_kernel_options());
  Api& api = kernel.api();

  const int before = drive_commands(api);
  const Answer moved = execute(api, kPeer, kMove);
  CHECK(moved.status == 200);
  CHECK(drive_commands(api) > before);

  const Principal guest{"peer-guest", Role::Guest, default_scopes(Role::Guest), "token"};
  const Answer refused = execute(api, guest, kMove);
  CHECK(refused.status == 403);
  CHECK(refused.body["required_scope"] == "control");

  CHECK(execute(api, kPeer, {{"type", "teleport"}}).status == 400);

  REQUIRE(call(api, "POST", "/api/stop").status == 200);
  const int stopped_at = drive_commands(api);
  const Answer blocked = execute(api, kPeer, kMove);
  CHECK(blocked.status == 423);
  CHECK(blocked.body["code"] == "ESTOP_ACTIVE");
  CHECK(drive_commands(api) == stopped_at);

  const http::Response audit_answer = call(api, "GET", "/api/audit");  // newest 100
  REQUIRE(audit_answer.status == 200);
  const json audit = json::parse(audit_answer.body)["entries"];
  int peer_entries = 0;
  for (const auto& entry : audit)
    if (entry["principal"] == "peer-alex" && entry["event"] == "POST /api/action move") ++peer_entries;
  CHECK(peer_entries == 2);  // the move and the blocked move, each as the R2R sender
}

TEST_CASE("an R2R command to an e-stopped robot is answered 105 by the node, through the real action path") {
  Kernel kernel(sim_rover(), embedded_kernel_options());
  Api& api = kernel.api();
  rcand::sdk::testing::ManualClock clock;
  r2r_test::LoopbackNetwork net;
  AuthSettings auth;
  auth.tokens = {{"fleet", Role::User, sha256_hex("fleet-token-for-the-kernel-test")}};
  const Authenticator authenticator(auth);
  auto make = [&](const std::string& name, CommandExecutor executor) {
    R2rSettings settings;
    settings.outbound_token = "fleet-token-for-the-kernel-test";
    return std::make_unique<R2rNode>(R2rNodeDeps{.identity = {name, "", {"teleop"}},
                                                 .clock = clock,
                                                 .authenticator = authenticator,
                                                 .settings = settings,
                                                 .status_source = {},
                                                 .command_executor = std::move(executor),
                                                 .transports = {&net.endpoint(name)},
                                                 .fleet_member = nullptr,
                                                 .log = nullptr,
                                                 .stop_executor = nullptr,
                                                 .after_stop = {}});
  };
  // bob's executor hands the command to the real Api; answers may come from a capability worker.
  std::mutex mutex;
  std::condition_variable cv;
  int answered = 0;
  auto bob = make("bob", [&](const Principal& who, json body, CommandDone done) {
    api.execute_action(who, std::move(body), [&, done](int status, json reply) {
      done(status, std::move(reply));
      std::lock_guard lock(mutex);
      ++answered;
      cv.notify_all();
    });
  });
  auto alex = make("alex", {});
  bob->start();
  alex->start();
  auto wait_answers = [&](int n) {
    std::unique_lock lock(mutex);
    REQUIRE(cv.wait_for(lock, std::chrono::seconds(10), [&] { return answered >= n; }));
  };

  alex->send(r2r_wire::MessageType::Command, kMove, "bob");
  net.pump();
  wait_answers(1);
  net.pump();
  CHECK(net.sent("error", "bob").empty());
  const int after_move = drive_commands(api);

  REQUIRE(call(api, "POST", "/api/stop").status == 200);
  const int stopped_at = drive_commands(api);
  CHECK(stopped_at >= after_move);
  alex->send(r2r_wire::MessageType::Command, kMove, "bob");
  net.pump();
  wait_answers(2);
  net.pump();
  const auto errors = net.sent("error", "bob", "alex");
  REQUIRE(errors.size() == 1);
  CHECK(errors[0].message["payload"]["code"] == 105);
  CHECK(drive_commands(api) == stopped_at);
  bob->stop();
  alex->stop();
}

namespace {

// The dispatcher's answer to `request` (with `note` for its audit entry), waited for: it may come from any thread.
rcand::sdk::Response dispatched(const KernelRequestDispatcher& dispatcher, rcand::sdk::Request request, json note = nullptr) {
  std::mutex mutex;
  std::condition_variable cv;
  std::optional<rcand::sdk::Response> answer;
  dispatcher.dispatch(std::move(request), std::move(note), [&](rcand::sdk::Response response) {
    std::lock_guard lock(mutex);
    answer = std::move(response);
    cv.notify_all();
  });
  std::unique_lock lock(mutex);
  REQUIRE(cv.wait_for(lock, std::chrono::seconds(10), [&] { return answer.has_value(); }));
  return *answer;
}

}  // namespace

namespace {

// A request as a plugin dispatches it for the caller whose `token` it carries (the CallerCredential rcand attached to
// the caller's own request). `named` is who the plugin claims it is for: never trusted.
rcand::sdk::Request for_caller(std::string method, std::string path, json body, const std::string& token, std::string id,
                               std::string named = "chat-user") {
  rcand::sdk::Request r;
  r.method = std::move(method);
  r.path = std::move(path);
  r.body = std::move(body);
  r.principal = std::move(named);
  r.role = Role::Creator;  // what a plugin claims does not count: the credential's role does
  r.message_id = std::move(id);
  if (!token.empty()) r.credential = std::make_shared<const CallerCredential>(std::string_view(token));
  return r;
}

}  // namespace

// The dispatcher plugins find as sdk::RequestDispatcher (the chat capability's way to act): the caller's request runs
// the kernel's own path with the caller's credential authorized again, so the caller's scopes are checked, the e-stop
// pre-check applies and the audit names the caller under the message id the plugin chose.
TEST_CASE("KernelRequestDispatcher: a plugin's request on a caller's behalf runs as that caller's HTTP request") {
  Kernel kernel(sim_rover(), embedded_kernel_options());
  Api& api = kernel.api();
  const KernelRequestDispatcher dispatcher(api);
  auto dispatch = [&](rcand::sdk::Request request) { return dispatched(dispatcher, std::move(request)); };

  const int before = drive_commands(api);
  CHECK(dispatch(for_caller("POST", "/api/action", kMove, kUserToken, "thought-1")).status == 200);
  CHECK(drive_commands(api) > before);
  const auto refused = dispatch(for_caller("POST", "/api/action", kMove, kGuestToken, "thought-2", "chat-user"));
  CHECK(refused.status == 403);  // the guest's credential, whatever the plugin named
  CHECK(refused.body["required_scope"] == "control");
  CHECK(dispatch(for_caller("GET", "/api/nowhere", nullptr, kUserToken, "")).status == 404);
  const auto status = dispatch(for_caller("GET", "/api/status", nullptr, kGuestToken, ""));
  CHECK(status.status == 200);
  CHECK(status.body.contains("capabilities"));

  // A credential rcand no longer accepts (a token removed by a config reload), or none at all: nothing runs.
  for (const std::string& token : {std::string("a-token-no-longer-configured"), std::string()}) {
    const auto unauthorized = dispatch(for_caller("POST", "/api/action", kMove, token, "thought-revoked"));
    CHECK(unauthorized.status == 401);
    CHECK(unauthorized.body["code"] == "UNAUTHORIZED");
  }

  CHECK(dispatch(for_caller("POST", "/api/stop", json::object(), kGuestToken, "thought-3")).status == 200);
  const int stopped_at = drive_commands(api);
  const auto blocked = dispatch(for_caller("POST", "/api/action", kMove, kUserToken, "thought-4"));
  CHECK(blocked.status == 423);
  CHECK(drive_commands(api) == stopped_at);

  const json audit = json::parse(call(api, "GET", "/api/audit").body)["entries"];
  std::set<std::string> ids;
  for (const auto& entry : audit)
    if (entry["principal"] == "chat-user") ids.insert(entry.value("message_id", ""));
  CHECK(ids.count("thought-1") == 1);
  CHECK(ids.count("thought-4") == 1);
}

// The note a plugin adds to the audit entry of its request (the chat's "ai" block): recorded with the entry when it
// keeps the SDK's rules, and the request refused unrun when it breaks them (a plugin bug must not forge an entry).
TEST_CASE("KernelRequestDispatcher: a plugin's audit note joins the entry; a note breaking the rules runs nothing") {
  Kernel kernel(sim_rover(), embedded_kernel_options());
  Api& api = kernel.api();
  const KernelRequestDispatcher dispatcher(api);
  auto dispatch = [&](std::string id, json note) {
    return dispatched(dispatcher, for_caller("POST", "/api/action", kMove, kUserToken, std::move(id)), std::move(note));
  };
  const json ai{{"provider", "grammar"}, {"model", "grammar-en-1"}, {"confidence", 0.9}, {"thought_id", "th-1"}};
  CHECK(dispatch("noted-1", json{{"ai", ai}}).status == 200);

  const int before = drive_commands(api);
  for (const json& bad : {json("text"), json{{"Ai", 1}}, json{{"principal", "root"}}, json{{"outcome", "ok"}},
                          json{{"ai", std::string(3000, 'x')}}, json{{"a-b", 1}}}) {
    INFO(bad.dump().substr(0, 80));
    const auto refused = dispatch("noted-bad", bad);
    CHECK(refused.status == 500);
    CHECK(refused.body["code"] == "INVALID_AUDIT_NOTE");
  }
  CHECK(drive_commands(api) == before);

  const json audit = json::parse(call(api, "GET", "/api/audit").body)["entries"];
  int noted = 0;
  for (const auto& entry : audit) {
    CHECK(entry.value("message_id", "") != "noted-bad");
    if (entry.value("message_id", "") != "noted-1") continue;
    ++noted;
    CHECK(entry["ai"] == ai);
    CHECK(entry["principal"] == "chat-user");
    CHECK(entry["event"] == "POST /api/action move");
  }
  CHECK(noted == 1);
}
