// Several R2R nodes in one process on a LoopbackNetwork, one manual clock, and a stand-in for the action route
// (scope check, e-stop gate, "motion" counter) so the node's dispatch is tested without a kernel.
#pragma once

#include <doctest/doctest.h>

#include <algorithm>
#include <chrono>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "libs/rcan/crypto.hpp"
#include "loopback_network.hpp"
#include "rcand/sdk/testing/manual_clock.hpp"
#include "services/r2r/r2r_node.hpp"

namespace r2r_test {

using namespace rcand;
using namespace rcand::kernel;
using namespace rcand::kernel::r2r;
using nlohmann::json;

inline const std::string kFleetToken = "fleet-token-0123456789abcdef";
inline const std::string kViewerToken = "viewer-token-0123456789abcdef";

struct Robot {
  std::string name;
  LocalStatus status;
  int moves = 0;  // commands the stand-in action route executed
  std::vector<std::string> command_principals;
  std::unique_ptr<Authenticator> auth;
  std::unique_ptr<R2rNode> node;
};

class Fleet {
 public:
  rcand::sdk::testing::ManualClock clock;
  LoopbackNetwork net;

  Robot& add(const std::string& name, std::vector<std::string> capabilities, std::optional<FleetPose> pose,
             R2rSettings settings = defaults()) {
    auto robot = std::make_unique<Robot>();
    Robot& r = *robot;
    r.name = name;
    r.status.pose = pose;
    AuthSettings auth;
    auth.tokens = {{"fleet", rcand::sdk::Role::User, sha256_hex(kFleetToken)},
                   {"viewer", rcand::sdk::Role::Guest, sha256_hex(kViewerToken)}};
    r.auth = std::make_unique<Authenticator>(auth);
    R2rNodeDeps deps{.identity = {name, "rcan://acme.rover." + name, std::move(capabilities)},
                     .clock = clock,
                     .authenticator = *r.auth,
                     .settings = std::move(settings),
                     .status_source = [&r] { return r.status; },
                     .command_executor = [&r](const Principal& who, json body, CommandDone done) {
                       const auto& scopes = who.scopes;
                       if (std::find(scopes.begin(), scopes.end(), rcand::sdk::Scope::Control) == scopes.end())
                         return done(403, {{"error", "lacks control"}, {"code", "INSUFFICIENT_PRIVILEGES"}});
                       if (r.status.estopped)
                         return done(423, {{"error", "e-stop is latched"}, {"code", "ESTOP_ACTIVE"}});
                       if (body["type"] != "move") return done(400, {{"error", "unknown action type"}, {"code", "BAD_REQUEST"}});
                       ++r.moves;
                       r.command_principals.push_back(who.name);
                       done(200, {{"ok", true}});
                     },
                     .cost_function = {},
                     .physics = {0.5, 0.01, 1.0},
                     .transports = {&net.endpoint(name)},
                     .log = nullptr};
    r.node = std::make_unique<R2rNode>(std::move(deps));
    r.node->start();
    robots_[name] = std::move(robot);
    return r;
  }

  static R2rSettings defaults() {
    R2rSettings s;
    s.outbound_token = kFleetToken;
    s.bid_window = std::chrono::milliseconds(1000);
    s.status_interval = std::chrono::milliseconds(1000);
    return s;
  }

  Robot& operator[](const std::string& name) { return *robots_.at(name); }

  // Ticks every node and delivers until quiet.
  void settle() {
    for (int round = 0; round < 10; ++round) {
      for (auto& [name, robot] : robots_) robot->node->tick();
      if (net.pump() == 0) break;
    }
  }
  void advance(std::chrono::milliseconds by) {
    clock.advance(by);
    settle();
  }

  // A message from `source` as raw JSON with the fleet token (tests that need malformed or foreign messages).
  json message(const std::string& type, json payload, const std::string& source = "outsider",
               std::optional<std::string> target = std::nullopt) const {
    json header{{"version", "1.0"}, {"timestamp", clock.wall_ms() / 1000.0}, {"source_id", source},
                {"auth", {{"token", kFleetToken}}}};
    if (target) header["target_id"] = *target;
    return {{"header", header}, {"type", type}, {"payload", std::move(payload)}};
  }

 private:
  std::map<std::string, std::unique_ptr<Robot>> robots_;
};

}  // namespace r2r_test
