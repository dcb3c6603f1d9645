// Several R2R nodes in one process on a LoopbackNetwork, one manual clock, and a stand-in for the action route
// (scope check, e-stop gate, "motion" counter) so the node's dispatch is tested without a kernel. Each robot also runs
// the fleet plugin's auctions (plugins/fleet, linked as rcand_fleet_logic) as rcand does: on an R2rLink of the plugin
// bridge, its callbacks queued on a worker (a fake scheduler run by settle()), bids priced with nav's trip timing.
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
#include "plugins/fleet/auctions.hpp"
#include "plugins/nav/waypoint_plan.hpp"
#include "rcand/sdk/testing/fake_scheduler.hpp"
#include "rcand/sdk/testing/manual_clock.hpp"
#include "services/r2r/plugin_bridge.hpp"
#include "services/r2r/r2r_node.hpp"

namespace r2r_test {

using namespace rcand;
using namespace rcand::kernel;
using namespace rcand::services::r2r;
using nlohmann::json;
using rcand::plugins::fleet::Auctions;
using rcand::plugins::fleet::FleetPoint;
using rcand::plugins::fleet::FleetSettings;
using rcand::plugins::fleet::TaskSpec;
using FleetPose = rcand::sdk::Pose2d;

inline const std::string kFleetToken = "fleet-token-0123456789abcdef";
inline const std::string kViewerToken = "viewer-token-0123456789abcdef";

// Every robot's trip timing, as nav offers it (sdk::TripEstimator): 0.5 m/s and 10 ms per degree at full speed.
inline const rcand::plugins::nav::TripTiming& trips() {
  static const rcand::plugins::nav::TripTiming timing({0.5, 0.01, 1.0});
  return timing;
}

// Members in the order the kernel builds them; destroyed the other way round (the auctions unsubscribe, the link goes,
// the bridge detaches, then the node stops).
struct Robot {
  std::string name;
  LocalStatus status;  // pose in the robot's own frame; tasks_held from `fleet` at each settle()
  int moves = 0;       // commands the stand-in action route executed
  std::vector<std::string> command_principals;
  std::vector<json> stops;  // {"principal", "body"} of each fleet e-stop the stand-in POST /api/stop latched
  bool defer_after_stop = false;  // keep what follows a fleet e-stop in after_stop_work, not inline
  std::vector<std::function<void()>> after_stop_work;
  std::unique_ptr<Authenticator> auth;
  std::unique_ptr<R2rNode> node;
  std::unique_ptr<PluginBridge> bridge;
  std::unique_ptr<rcand::sdk::testing::FakeWorker> worker;  // the fleet plugin's "r2r" worker
  std::unique_ptr<rcand::sdk::R2rLink> link;
  std::unique_ptr<Auctions> fleet;  // the fleet plugin's auctions on this robot
};

class Fleet {
 public:
  rcand::sdk::testing::ManualClock clock;
  LoopbackNetwork net;
  // The plugin workers' queue, on a clock of its own: running a task moves its clock to the task's due time, which
  // must never move the robots' wall clock back.
  rcand::sdk::testing::ManualClock worker_clock;
  rcand::sdk::testing::FakeScheduler scheduler{worker_clock};

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
    FleetSettings fleet_settings;
    fleet_settings.robot_name = name;
    fleet_settings.capabilities = capabilities;
    fleet_settings.origin = settings.origin;
    R2rNodeDeps deps{.identity = {name, "rcan://acme.rover." + name, std::move(capabilities)},
                     .clock = clock,
                     .authenticator = *r.auth,
                     .settings = std::move(settings),
                     .status_source = [&r] { return r.status; },
                     .command_executor =
                         [&r](const Principal& who, json body, CommandDone done) {
                           const auto& scopes = who.scopes;
                           if (std::find(scopes.begin(), scopes.end(), rcand::sdk::Scope::Control) == scopes.end())
                             return done(403, {{"error", "lacks control"}, {"code", "INSUFFICIENT_PRIVILEGES"}});
                           if (r.status.estopped) return done(423, {{"error", "e-stop is latched"}, {"code", "ESTOP_ACTIVE"}});
                           if (body["type"] != "move")
                             return done(400, {{"error", "unknown action type"}, {"code", "BAD_REQUEST"}});
                           ++r.moves;
                           r.command_principals.push_back(who.name);
                           done(200, {{"ok", true}});
                         },
                     .transports = {&net.endpoint(name)},
                     .fleet_member = nullptr,  // only robots heard from are relayed to
                     .log = nullptr,
                     .stop_executor =
                         [&r](const Principal& who, json body) {
                           r.status.estopped = true;
                           r.status.state = "estop";
                           r.stops.push_back({{"principal", who.name}, {"body", std::move(body)}});
                         },
                     .after_stop =
                         [&r](std::function<void()> work) {
                           if (r.defer_after_stop) r.after_stop_work.push_back(std::move(work));
                           else work();
                         }};
    r.node = std::make_unique<R2rNode>(std::move(deps));
    r.node->start();
    r.bridge = std::make_unique<PluginBridge>(
        [&r]() -> const rcand::sdk::FleetAuctions* { return r.fleet ? &r.fleet->service() : nullptr; });
    r.bridge->attach(*r.node);
    r.worker = std::make_unique<rcand::sdk::testing::FakeWorker>(scheduler, worker_clock, name + ".r2r");
    r.link = r.bridge->make_link(*r.worker, name + " (org.rcand.fleet)");
    const FleetPose origin = fleet_settings.origin;
    r.fleet = std::make_unique<Auctions>(Auctions::Deps{.link = *r.link,
                                                        .clock = clock,
                                                        .settings = std::move(fleet_settings),
                                                        .position = [&r, origin]() -> std::optional<FleetPose> {
                                                          if (!r.status.pose) return std::nullopt;
                                                          return rcand::sdk::compose(origin, *r.status.pose);
                                                        },
                                                        .trips = [] { return &trips(); },
                                                        .log = nullptr,
                                                        .due_changed = {}});  // the fixture ticks by hand
    r.fleet->subscribe();
    r.bridge->sync_cost();
    robots_[name] = std::move(robot);
    return r;
  }

  static R2rSettings defaults() {
    R2rSettings s;
    s.outbound_token = kFleetToken;
    s.status_interval = std::chrono::milliseconds(1000);
    return s;
  }

  Robot& operator[](const std::string& name) { return *robots_.at(name); }

  // Ticks every node and its auctions, delivers, and runs what the deliveries queued on the plugin workers, until
  // quiet.
  void settle() {
    for (int round = 0; round < 40; ++round) {
      for (auto& [name, robot] : robots_) {
        robot->status.tasks_held = robot->fleet->tasks_held();  // what rcand's status source reads from the plugin
        robot->node->tick();
        robot->fleet->tick();
      }
      const int delivered = net.pump();
      const std::size_t ran = scheduler.run_due();
      if (delivered == 0 && ran == 0) break;
    }
  }
  void advance(std::chrono::milliseconds by) {
    clock.advance(by);
    settle();
  }

  // A message from `source` as raw JSON with the fleet token (tests that need malformed or foreign messages).
  json message(const std::string& type, json payload, const std::string& source = "outsider",
               std::optional<std::string> target = std::nullopt) const {
    json header{
        {"version", "1.0"}, {"timestamp", clock.wall_ms() / 1000.0}, {"source_id", source}, {"auth", {{"token", kFleetToken}}}};
    if (target) header["target_id"] = *target;
    return {{"header", header}, {"type", type}, {"payload", std::move(payload)}};
  }

 private:
  std::map<std::string, std::unique_ptr<Robot>> robots_;
};

}  // namespace r2r_test
