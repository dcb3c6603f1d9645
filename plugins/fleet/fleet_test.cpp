// The fleet plugin on the SDK's fake host: what it subscribes to and sends over its R2rLink, the FleetAuctions service
// rcand's R2R service finds, bids priced by a TripEstimator and a PoseSource found as services, and shutdown.
#include <doctest/doctest.h>

#include <rcand/sdk/interfaces/fleet_auctions.hpp>
#include <rcand/sdk/testing/fake_host.hpp>

#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "fleet.hpp"

extern "C" const rcand_plugin_descriptor* RCAND_ENTRY_FUNCTION(void);  // plugin.cpp

using namespace std::chrono_literals;
using rcand::sdk::FleetAuctions;
using rcand::sdk::Json;
using rcand::sdk::R2rMessage;
using rcand::sdk::Response;
using rcand::sdk::testing::FakeHost;

namespace {

Json fleet_manifest() {
  std::ifstream in(std::string(RCAND_SOURCE_DIR) + "/manifests/fleet.json");
  std::stringstream text;
  text << in.rdbuf();
  return Json::parse(text.str());
}

// A robot named alpha at fleet (10, 0) facing +y: its own frame starts there (runtime.r2r.origin).
Json robot_config() {
  return {{"metadata", {{"robot_name", "alpha"}}},
          {"rcan_protocol", {{"capabilities", {"status", "nav", "teleop", "org.rcand.fleet"}}}},
          {"runtime",
           {{"r2r", {{"enabled", true}, {"origin", {{"x", 10}, {"y", 0}, {"heading_deg", 90}}}, {"bid_window_ms", 500}}}}}};
}

// Seconds = straight-line distance, whatever the heading and speed: easy numbers to check.
class StraightLine final : public rcand::sdk::TripEstimator {
 public:
  std::optional<double> trip_seconds(const rcand::sdk::Pose2d& from, double x, double y, double) const noexcept override {
    last_from = from;
    return std::hypot(x - from.x_m, y - from.y_m);
  }
  mutable rcand::sdk::Pose2d last_from;
};

class FixedPose final : public rcand::sdk::PoseSource {
 public:
  rcand::sdk::PoseReading read() const noexcept override { return {true, {2.0, 0.0, 0.0}, false}; }
};

R2rMessage message(std::string type, Json payload, std::string from = "bravo", std::optional<std::string> to = "alpha") {
  return {std::move(type), std::move(from), std::move(to), 1.0, std::move(payload), "fleet", "ws"};
}

struct Plugin {
  FakeHost host{robot_config()};
  StraightLine trips;
  FixedPose pose;
  rcand::plugins::fleet::Fleet* fleet = nullptr;

  explicit Plugin(bool r2r = true) {
    if (r2r) host.enable_r2r();
    REQUIRE(rcand::sdk::offer<rcand::sdk::TripEstimator>(host, trips));
    REQUIRE(rcand::sdk::offer<rcand::sdk::PoseSource>(host, pose));
    host.load(RCAND_ENTRY_FUNCTION, fleet_manifest());
    fleet = &dynamic_cast<rcand::plugins::fleet::Fleet&>(host.add_capability("org.rcand.fleet"));
  }
  const FleetAuctions* auctions() const { return rcand::sdk::find<FleetAuctions>(host); }
  std::vector<FakeHost::R2rSent> sent(const std::string& type) const {
    std::vector<FakeHost::R2rSent> out;
    for (const auto& s : host.r2r_sent())
      if (s.type == type) out.push_back(s);
    return out;
  }
};

}  // namespace

TEST_CASE("fleet: without R2R it starts idle and offers nothing") {
  Plugin plugin(false);
  CHECK(plugin.auctions() == nullptr);
  CHECK(plugin.fleet->status() == Json{{"r2r", false}});
}

TEST_CASE("fleet: bids on a task request from the PoseSource's pose placed by runtime.r2r.origin, priced by the TripEstimator") {
  Plugin plugin;
  REQUIRE(plugin.auctions() != nullptr);
  // alpha's own (2, 0) is fleet (10, 2); the task at (10, 5) is 3 m away.
  CHECK(
      plugin.host.deliver_r2r(message(
          "task_request",
          {{"task_id", "T1"}, {"required_capabilities", {"teleop"}}, {"location", {{"x", 10}, {"y", 5}}}, {"bid_deadline", 1e12}},
          "bravo", std::nullopt)) == 1);
  CHECK(plugin.sent("negotiation").empty());  // on the worker, not inline
  plugin.host.run_pending();
  CHECK(plugin.sent("negotiation").empty());  // a bid_deadline further off than 300 s gets no bid

  const double soon = static_cast<double>(plugin.host.clock().wall_ms()) / 1000.0 + 1.0;
  plugin.host.deliver_r2r(message(
      "task_request",
      {{"task_id", "T2"}, {"required_capabilities", {"teleop"}}, {"location", {{"x", 10}, {"y", 5}}}, {"bid_deadline", soon}},
      "bravo", std::nullopt));
  plugin.host.run_pending();
  const auto bids = plugin.sent("negotiation");
  REQUIRE(bids.size() == 1);
  CHECK(bids[0].target == "bravo");
  CHECK(bids[0].payload["action"] == "bid");
  CHECK(bids[0].payload["cost"].get<double>() == doctest::Approx(3.0));
  CHECK(plugin.trips.last_from.x_m == doctest::Approx(10.0));
  CHECK(plugin.trips.last_from.y_m == doctest::Approx(2.0));
  CHECK(plugin.trips.last_from.heading_deg == doctest::Approx(90.0));

  // The award: accepted, and the task is held (what rcand's status and GET /api/r2r/peers report).
  plugin.host.deliver_r2r(message("negotiation", {{"task_id", "T2"}, {"action", "award"}}));
  plugin.host.run_pending();
  const auto responses = plugin.sent("task_response");
  REQUIRE(responses.size() == 1);
  CHECK(responses[0].payload["accepted"] == true);
  CHECK(plugin.auctions()->tasks_held() == 1);
  CHECK(plugin.auctions()->held_tasks()[0]["requester"] == "bravo");
  // A second requester's award for it: 102, its ref naming that requester's header.
  plugin.host.deliver_r2r(message("negotiation", {{"task_id", "T2"}, {"action", "award"}}, "charlie"));
  plugin.host.run_pending();
  const auto errors = plugin.sent("error");
  REQUIRE(errors.size() == 1);
  CHECK(errors[0].payload["code"] == 102);
  CHECK(errors[0].payload["ref"]["source_id"] == "charlie");
  CHECK(errors[0].target == "charlie");
}

TEST_CASE("fleet: POST /api/r2r/auction through the service: 400 naming the field, 202, then 200 once decided") {
  Plugin plugin;
  const FleetAuctions& auctions = *plugin.auctions();
  std::vector<Response> answers;
  auto keep = [&answers](const Response& r) { answers.push_back(r); };

  auctions.open(Json{{"location", {{"x", "north"}}}}, keep);
  REQUIRE(answers.size() == 1);
  CHECK(answers[0].status == 400);
  CHECK(answers[0].body["field"] == "location");
  auctions.open(Json{{"timeout_ms", 0}}, keep);
  CHECK(answers.back().body["field"] == "timeout_ms");
  plugin.host.fail_r2r_sends("the link refused it");  // rcand's link refuses a payload the seed's rules refuse
  auctions.open(Json{{"task_id", "X"}}, keep);
  CHECK(answers.back().status == 400);
  CHECK(answers.back().body["field"] == "body");
  CHECK(answers.back().body["error"] == "the link refused it");
  plugin.host.fail_r2r_sends("");
  answers.clear();

  auctions.open(Json{{"task_id", "A1"}, {"wait", false}}, keep);
  REQUIRE(answers.size() == 1);
  CHECK(answers[0].status == 202);
  CHECK(answers[0].body == Json{{"task_id", "A1"}, {"state", "bidding"}});
  const auto requests = plugin.sent("task_request");
  REQUIRE(requests.size() >= 1);
  CHECK_FALSE(requests.back().target);
  CHECK(requests.back().payload["task_id"] == "A1");
  CHECK(auctions.result("A1").body["state"] == "bidding");
  CHECK(auctions.result("nope").status == 404);

  answers.clear();
  auctions.open(Json{{"task_id", "A2"}, {"timeout_ms", 5000}}, keep);
  CHECK(answers.empty());  // waits for the decision
  plugin.host.deliver_r2r(
      message("negotiation", {{"task_id", "A2"}, {"action", "bid"}, {"cost", 4.5}, {"capabilities", Json::array()}}));
  plugin.host.advance(600ms);  // past the 500 ms bid window: the plugin's tick awards
  const auto awards = plugin.sent("negotiation");
  REQUIRE_FALSE(awards.empty());
  CHECK(awards.back().payload["action"] == "award");
  CHECK(awards.back().target == "bravo");
  plugin.host.deliver_r2r(message("task_response", {{"task_id", "A2"}, {"accepted", true}, {"estimated_time", 4.5}}));
  plugin.host.run_pending();
  REQUIRE(answers.size() == 1);
  CHECK(answers[0].status == 200);
  CHECK(answers[0].body["state"] == "assigned");
  CHECK(answers[0].body["winner"] == "bravo");
  CHECK(answers[0].body["decided"] == true);
  CHECK(answers[0].body["elapsed_ms"].get<double>() >= 500.0);

  // Undecided at timeout_ms: answered with what there is.
  answers.clear();
  auctions.open(Json{{"task_id", "A3"}, {"timeout_ms", 100}}, keep);
  plugin.host.advance(150ms);
  REQUIRE(answers.size() == 1);
  CHECK(answers[0].body["decided"] == false);
  CHECK(answers[0].body["state"] == "bidding");
}

TEST_CASE("fleet: an auction is decided at its deadline though the plugin ticks only every 250 ms at rest") {
  // A bid window shorter than the idle tick: opening the auction brings the tick forward to its deadline.
  Json config = robot_config();
  config["runtime"]["r2r"]["bid_window_ms"] = 100;
  FakeHost host{config};
  host.enable_r2r();
  host.load(RCAND_ENTRY_FUNCTION, fleet_manifest());
  host.add_capability("org.rcand.fleet");
  const FleetAuctions& auctions = *rcand::sdk::find<FleetAuctions>(host);
  host.advance(100ms);                                                              // mid-way between two idle ticks
  auctions.open(Json{{"task_id", "Q1"}, {"wait", false}}, [](const Response&) {});  // the opening alone wakes the tick
  host.deliver_r2r(
      message("negotiation", {{"task_id", "Q1"}, {"action", "bid"}, {"cost", 1.0}, {"capabilities", Json::array()}}));
  host.advance(101ms);
  std::vector<Json> awards;
  for (const auto& s : host.r2r_sent())
    if (s.type == "negotiation" && s.payload.value("action", "") == "award") awards.push_back(s.payload);
  REQUIRE(awards.size() == 1);  // at 100 ms, not at the next idle tick (250 ms)
  CHECK(awards[0]["task_id"] == "Q1");
}

TEST_CASE("fleet: a price handed on from R2rLink::set_cost_function replaces the default until cleared") {
  Plugin plugin;
  const FleetAuctions& auctions = *plugin.auctions();
  auctions.set_cost_override([](const Json& task, const std::optional<rcand::sdk::R2rPose>& pose, std::size_t queue) {
    return std::optional<double>(task["task_id"] == "P1" && pose && pose->y == 2.0 && queue == 0 ? 7.0 : 99.0);
  });
  const double soon = static_cast<double>(plugin.host.clock().wall_ms()) / 1000.0 + 1.0;
  plugin.host.deliver_r2r(message("task_request", {{"task_id", "P1"}, {"bid_deadline", soon}}, "bravo", std::nullopt));
  plugin.host.run_pending();
  REQUIRE(plugin.sent("negotiation").size() == 1);
  CHECK(plugin.sent("negotiation")[0].payload["cost"] == 7.0);

  auctions.set_cost_override([](const Json&, const std::optional<rcand::sdk::R2rPose>&, std::size_t) -> std::optional<double> {
    throw std::runtime_error("broken pricing");
  });
  plugin.host.deliver_r2r(message("task_request", {{"task_id", "P2"}, {"bid_deadline", soon}}, "bravo", std::nullopt));
  plugin.host.run_pending();
  CHECK(plugin.sent("negotiation").size() == 1);  // a throw is "no bid", and the plugin keeps running
  CHECK(plugin.host.task_failures().empty());

  auctions.set_cost_override({});  // the default: no location, an empty queue
  plugin.host.deliver_r2r(message("task_request", {{"task_id", "P3"}, {"bid_deadline", soon}}, "bravo", std::nullopt));
  plugin.host.run_pending();
  REQUIRE(plugin.sent("negotiation").size() == 2);
  CHECK(plugin.sent("negotiation")[1].payload["cost"] == 0.0);
}

TEST_CASE("fleet: shutdown answers a request still waiting with 503 and stops listening") {
  std::vector<Response> answers;
  {
    Plugin plugin;
    plugin.auctions()->open(Json{{"task_id", "S1"}}, [&answers](const Response& r) { answers.push_back(r); });
    CHECK(answers.empty());
  }  // the host shuts the plugin down
  REQUIRE(answers.size() == 1);
  CHECK(answers[0].status == 503);
  CHECK(answers[0].body["code"] == "UNAVAILABLE");
}
