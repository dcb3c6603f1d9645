// Plugins and R2R: the SDK's R2rLink on the fake host (what a vendor tests with), and the kernel's bridge between
// a node and plugin workers (callbacks on the worker, validated messages only, links end with their instance).
#include <doctest/doctest.h>

#include <rcand/sdk/plugin.hpp>
#include <rcand/sdk/testing/fake_host.hpp>
#include <rcand/sdk/testing/fake_scheduler.hpp>

#include "fleet_fixture.hpp"
#include "services/r2r/plugin_bridge.hpp"

using namespace r2r_test;
using namespace std::chrono_literals;
using rcand::sdk::Json;
using rcand::sdk::R2rMessage;

namespace {

// A vendor-style capability: answers every direct task_request with task_response, and prices bids by queue only.
class Dispatcher final : public rcand::sdk::Capability {
 public:
  explicit Dispatcher(rcand::sdk::PluginContext& ctx) {
    if (const auto* links = rcand::sdk::find<rcand::sdk::R2rLinks>(ctx))
      link_ = links->make_link(ctx.worker("r2r"), "com.test.dispatch");
    if (link_ == nullptr) return;  // this robot has no R2R: the capability still works locally
    link_->subscribe("task_request", [this](const R2rMessage& m) {
      ++handled;
      link_->send("task_response", {{"task_id", m.payload["task_id"]}, {"accepted", true}, {"estimated_time", 7}}, m.source_id);
    });
    link_->set_cost_function([](const Json&, const std::optional<rcand::sdk::R2rPose>&, std::size_t queue) {
      return std::optional<double>(1.0 + static_cast<double>(queue));
    });
  }
  std::vector<rcand::sdk::Route> routes() override { return {}; }
  std::unique_ptr<rcand::sdk::R2rLink> link_;
  int handled = 0;
};

void register_dispatcher(rcand::sdk::Registrar& r) {
  r.add_capability({"com.test.dispatch", false},
                   [](rcand::sdk::PluginContext& ctx) { return std::make_unique<Dispatcher>(ctx); });
}

}  // namespace

RCAND_PLUGIN("com.test.dispatch", "1.0.0", register_dispatcher)

TEST_CASE("fake host: a plugin subscribes, receives on its worker, sends, and installs a cost function") {
  rcand::sdk::testing::FakeHost host;
  host.enable_r2r();
  host.load(RCAND_ENTRY_FUNCTION);
  auto& dispatcher = dynamic_cast<Dispatcher&>(host.add_capability("com.test.dispatch"));
  REQUIRE(dispatcher.link_ != nullptr);
  REQUIRE(host.r2r_cost_function());
  CHECK(*host.r2r_cost_function()(Json::object(), std::nullopt, 2) == 3.0);

  R2rMessage request{"task_request", "alex", std::nullopt, 1.0, {{"task_id", "T1"}}, "fleet", "mqtt"};
  CHECK(host.deliver_r2r(request) == 1);
  CHECK(dispatcher.handled == 0);  // queued on the worker, not run inline
  host.run_pending();
  CHECK(dispatcher.handled == 1);
  REQUIRE(host.r2r_sent().size() == 1);
  CHECK(host.r2r_sent()[0].type == "task_response");
  CHECK(host.r2r_sent()[0].target == "alex");
  CHECK(host.r2r_sent()[0].payload["estimated_time"] == 7);

  CHECK(host.deliver_r2r({"status", "alex", std::nullopt, 1.0, Json::object(), "fleet", "udp"}) == 0);
  CHECK_FALSE(dispatcher.link_->send("teleport", Json::object(), std::nullopt).ok);
  CHECK_THROWS_AS(dispatcher.link_->subscribe("teleport", [](const R2rMessage&) {}), std::invalid_argument);
  host.fail_r2r_sends("R2R is not running on this robot");
  CHECK(dispatcher.link_->send("status", Json::object(), std::nullopt).error == "R2R is not running on this robot");
}

TEST_CASE("fake host: without R2R the context offers no link") {
  rcand::sdk::testing::FakeHost host;
  host.load(RCAND_ENTRY_FUNCTION);
  auto& dispatcher = dynamic_cast<Dispatcher&>(host.add_capability("com.test.dispatch"));
  CHECK(dispatcher.link_ == nullptr);
}

TEST_CASE("kernel bridge: plugin callbacks run on the plugin worker with validated messages; links end cleanly") {
  Fleet fleet;
  Robot& alex = fleet.add("alex", {"nav"}, FleetPose{});
  Robot& bob = fleet.add("bob", {"nav"}, FleetPose{});
  rcand::sdk::testing::ManualClock worker_clock;
  rcand::sdk::testing::FakeScheduler scheduler(worker_clock);
  rcand::sdk::testing::FakeWorker worker(scheduler, worker_clock, "plugin.r2r");

  // Like rcand's: prices set on this bridge's links go to bob's fleet plugin.
  PluginBridge bridge([&bob] { return &bob.fleet->service(); });
  auto link = bridge.make_link(worker, "com.test.dispatch (dispatch)");
  std::vector<R2rMessage> seen;
  const auto id = link->subscribe("task_request", [&](const R2rMessage& m) { seen.push_back(m); });
  CHECK_FALSE(link->send("status", Json::object(), std::nullopt).ok);  // not attached yet
  bridge.attach(*bob.node);                                            // like the kernel: after the plugins started

  alex.node->send(rcand::r2r_wire::MessageType::TaskRequest, {{"task_id", "T1"}, {"description", "d"}}, "bob");
  std::vector<json> replies;
  fleet.net.inject("bob", fleet.message("task_request", {{"task_id", 5}}).dump(), &replies);  // invalid: never relayed
  fleet.settle();
  CHECK(seen.empty());  // queued on the plugin's worker, not run on the transport's thread
  scheduler.run_due();
  REQUIRE(seen.size() == 1);
  CHECK(seen[0].type == "task_request");
  CHECK(seen[0].source_id == "alex");
  CHECK(seen[0].principal == "fleet");
  CHECK(seen[0].payload["task_id"] == "T1");

  // A plugin's send goes out through the node, validated.
  const auto sent = link->send("status", {{"battery", 40}}, std::nullopt);
  CHECK(sent.ok);
  fleet.net.pump();
  const auto bad = link->send("task_response", {{"task_id", "T1"}}, "alex");
  CHECK_FALSE(bad.ok);
  CHECK(bad.field == "/payload/accepted");

  // The plugin's cost function prices bob's bids (the fleet plugin calls it); when its link goes away the default
  // returns.
  link->set_cost_function([](const Json& task, const std::optional<rcand::sdk::R2rPose>&, std::size_t) {
    return std::optional<double>(task["task_id"] == "A1" ? 42.0 : 1.0);
  });
  TaskSpec task;
  task.task_id = "A1";
  alex.fleet->open_auction(task);
  fleet.settle();
  CHECK((*alex.fleet->auction_result("A1"))["bids"][0]["cost"] == 42.0);

  link->unsubscribe(id);
  alex.node->send(rcand::r2r_wire::MessageType::TaskRequest, {{"task_id", "T2"}}, "bob");
  fleet.settle();
  scheduler.run_due();
  CHECK(seen.size() == 1);

  link.reset();
  task.task_id = "A2";
  alex.fleet->open_auction(task);
  fleet.settle();
  // The default again: no location, so only the queue counts (bob holds T1 and T2: 2 x 30 s).
  CHECK((*alex.fleet->auction_result("A2"))["bids"][0]["cost"] == 60.0);
  bridge.detach();
}
