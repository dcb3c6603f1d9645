// The chat capability on the SDK's fake host, for chat's unit tests: the robot config, rcand's RequestDispatcher as a
// double, a scripted brain plugin ("spy"), and POST /api/command / the other routes called as the kernel would.
#pragma once

#include <doctest/doctest.h>

#include <rcand/sdk/interfaces/request_dispatcher.hpp>
#include <rcand/sdk/testing/fake_host.hpp>
#include <rcand/sdk/testing/recording_stream.hpp>

#include <algorithm>
#include <fstream>
#include <mutex>

#include "chat.hpp"

extern "C" const rcand_plugin_descriptor* RCAND_ENTRY_FUNCTION(void);

namespace chat_test {

using nlohmann::json;
using rcand::sdk::Response;
using rcand::sdk::Role;
using rcand::sdk::testing::FakeHost;
using rcand::sdk::testing::RecordingStream;
namespace sdk = rcand::sdk;

inline json manifest() {
  std::ifstream in(RCAND_SOURCE_DIR "/manifests/chat.json");
  REQUIRE(in.good());
  return json::parse(in);
}

inline json rover_config(json chat = json::object(), json agent = {{"provider", "grammar"}}) {
  if (!chat.contains("phrases"))
    chat["phrases"] = {
        {{"say", {"close the gripper", "grab it"}},
         {"action", {{"method", "POST"}, {"path", "/api/cap/com.acme.gripper/grip"}, {"body", {{"state", "close"}}}}}},
        {{"say", "open the gripper"},
         {"action", {{"method", "POST"}, {"path", "/api/cap/com.acme.gripper/grip"}, {"body", {{"state", "open"}}}}}}};
  return {{"rcan_protocol", {{"capabilities", {"status", "teleop", "nav", "vision", "chat", "com.acme.gripper"}}}},
          {"physics", {{"wheel_circumference_m", 0.21}, {"turn_time_per_deg_s", 0.008}, {"max_wheel_rps", 1.0}}},
          {"agent", agent},
          {"runtime", {{"capabilities", {{"chat", chat}}}}}};
}

// The credential a Fixture request carries, as rcand attaches its own (opaque to chat).
inline std::shared_ptr<const sdk::Credential> credential_of(const std::string& principal, Role role) {
  auto c = std::make_shared<FakeHost::TestCredential>();
  c->principal = principal;
  c->role = role;
  return c;
}

// rcand's RequestDispatcher as a double: records each request and answers `answer` at once - or, as rcand does when it
// authorizes the caller again, 401 for a request without a credential or with one in `revoked`.
struct Dispatcher final : sdk::RequestDispatcher {
  mutable std::vector<sdk::Request> requests;
  mutable std::vector<json> audit_notes;
  Response answer = Response::ok({{"ok", true}});
  std::vector<std::string> revoked;  // principals whose credential no longer authorizes anything
  void dispatch(sdk::Request request, json audit_note, std::function<void(Response)> done) const noexcept override {
    requests.push_back(request);
    audit_notes.push_back(std::move(audit_note));
    const auto* caller = dynamic_cast<const FakeHost::TestCredential*>(request.credential.get());
    if (caller == nullptr || std::find(revoked.begin(), revoked.end(), caller->principal) != revoked.end())
      return done(Response::error(401, "UNAUTHORIZED", "unknown or invalid token"));
    done(answer);
  }
};

// A brain plugin as a double, offered as provider "spy".
struct SpyBrain final : sdk::Brain {
  std::function<sdk::Proposal(const sdk::BrainRequest&, sdk::CancelToken)> answer;
  mutable int calls = 0;
  std::string_view provider() const noexcept override { return "spy"; }
  sdk::Proposal propose(const sdk::BrainRequest& request, const sdk::BrainContext&,
                        sdk::CancelToken cancel) const noexcept override {
    ++calls;
    return answer(request, cancel);
  }
};

inline sdk::Proposal spy_says(json action, std::optional<double> confidence = 0.9) {
  sdk::Proposal p;
  p.raw_text = "spy reading";
  p.action = std::move(action);
  p.confidence = confidence;
  p.brain = "spy";
  p.model = "spy-1";
  return p;
}

inline json waypoint(double d, double h, double s = 0.5) {
  return {{"method", "POST"}, {"path", "/api/nav/waypoint"}, {"body", {{"distance_m", d}, {"heading_deg", h}, {"speed", s}}}};
}

struct Fixture {
  FakeHost host;
  Dispatcher dispatcher;
  SpyBrain spy;
  explicit Fixture(json config = rover_config()) : host(std::move(config)) {
    host.load(RCAND_ENTRY_FUNCTION, manifest());  // provides and the settings schema, as the kernel checks them
    REQUIRE(sdk::offer<sdk::RequestDispatcher>(host, dispatcher));
    REQUIRE(host.offer_service(sdk::brain_service_id("spy"), static_cast<const sdk::Brain*>(&spy)));
    host.add_capability("chat");
  }
  rcand::plugins::chat::Chat& chat() { return host.capability<rcand::plugins::chat::Chat>("chat"); }

  // POST /api/command as the kernel hands it to the stream route; the brain runs only on run_pending().
  std::shared_ptr<RecordingStream> post(json body, Role role = Role::User, bool run = true, std::string principal = "alice") {
    sdk::Request request;
    request.method = "POST";
    request.path = "/api/command";
    request.body = std::move(body);
    request.principal = principal;
    request.role = role;
    request.scopes = sdk::default_scopes_of(role);
    request.credential = credential_of(principal, role);
    request.message_id = "m-42";
    auto writer = std::make_shared<RecordingStream>();
    stream_route("POST", "/api/command").handler(request, writer);
    if (run) host.run_pending();
    return writer;
  }
  sdk::StreamRoute stream_route(const std::string& method, const std::string& path) {
    for (auto& r : chat().stream_routes())
      if (r.method == method && r.path == path) return r;
    FAIL("no stream route " << method << " " << path);
    return {};
  }
  // A plain route of chat's (GET /api/thoughts/*, GET /api/hitl/pending), called as the kernel would.
  // `scopes`: what the caller's credential grants (default: every scope of `role`; a narrowed JWT grants fewer).
  Response get(const std::string& path, Role role = Role::User, std::optional<std::vector<sdk::Scope>> scopes = std::nullopt) {
    sdk::Request request;
    request.method = "GET";
    request.path = path;
    request.role = role;
    request.scopes = scopes ? *scopes : sdk::default_scopes_of(role);
    request.principal = "reader";
    request.credential = credential_of(request.principal, role);
    for (auto& r : chat().routes()) {
      const bool prefix = r.path.ends_with('*');
      if (r.method == "GET" && (prefix ? path.rfind(r.path.substr(0, r.path.size() - 1), 0) == 0 : path == r.path))
        return r.handler(request);
    }
    FAIL("no route for " << path);
    return {};
  }
  // POST /api/hitl/authorize as `role`.
  std::shared_ptr<RecordingStream> authorize(json body, Role role = Role::Owner) {
    sdk::Request request;
    request.method = "POST";
    request.path = "/api/hitl/authorize";
    request.body = std::move(body);
    request.principal = "olivia";
    request.role = role;
    request.scopes = sdk::default_scopes_of(role);
    request.credential = credential_of(request.principal, role);
    auto writer = std::make_shared<RecordingStream>();
    stream_route("POST", "/api/hitl/authorize").handler(request, writer);
    host.run_pending();
    return writer;
  }
  std::shared_ptr<RecordingStream> say(const std::string& instruction, Role role = Role::User, std::string principal = "alice") {
    return post({{"instruction", instruction}}, role, true, std::move(principal));
  }
};

}  // namespace chat_test
