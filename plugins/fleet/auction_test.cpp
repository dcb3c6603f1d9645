// The auction's pure logic (moved here with it from services/r2r): requester and bidder sides, the default price
// (nav's trip time through its TripEstimator), the fleet frame, and the memory bounds.
#include <doctest/doctest.h>

#include <cmath>
#include <set>

#include "../nav/waypoint_plan.hpp"  // nav's TripEstimator: the numbers bids are priced with
#include "auction.hpp"

using namespace rcand::plugins::fleet;
using json = rcand::sdk::Json;

namespace {

TaskSpec fetch_task() {
  TaskSpec task;
  task.task_id = "T1";
  task.description = "fetch";
  task.required_capabilities = {"nav", "arm"};
  task.location = FleetPoint{3.0, 4.0};
  return task;
}

Bid bid(const std::string& who, double cost, std::vector<std::string> caps = {"nav", "arm"}) {
  return Bid{who, cost, std::move(caps), 0.0};
}

}  // namespace

TEST_CASE("auctioneer: the next deadline is the earliest bid deadline, then the award's, none once decided") {
  Auctioneer auctioneer;
  CHECK_FALSE(auctioneer.next_deadline());
  auctioneer.open(fetch_task(), 1.0, 100.0);
  REQUIRE(auctioneer.next_deadline());
  CHECK(*auctioneer.next_deadline() == 101.0);
  auctioneer.on_bid("T1", bid("bob", 5.0));
  REQUIRE(auctioneer.tick(101.0).size() == 1);  // awarded to bob: the winner's grace runs
  REQUIRE(auctioneer.next_deadline());
  CHECK(*auctioneer.next_deadline() == doctest::Approx(101.0 + kWinnerGraceS));
  CHECK(auctioneer.on_task_response("bob", "T1", true, 5.0, 101.2).empty());
  CHECK_FALSE(auctioneer.next_deadline());  // assigned: nothing left to tick for
}

TEST_CASE("auctioneer: the lowest capable bid wins at bid_deadline; ties go to the lowest name") {
  Auctioneer auctioneer;
  const auto opened = auctioneer.open(fetch_task(), 1.0, 100.0);
  REQUIRE(opened.size() == 1);
  CHECK(opened[0].type == "task_request");
  CHECK_FALSE(opened[0].target);
  CHECK(opened[0].payload["bid_deadline"] == 101.0);
  CHECK(opened[0].payload["required_capabilities"] == json({"nav", "arm"}));
  CHECK(opened[0].payload["location"]["x"] == 3.0);

  auctioneer.on_bid("T1", bid("carol", 5.0));
  auctioneer.on_bid("T1", bid("bob", 5.0));
  auctioneer.on_bid("T1", bid("dave", 1.0, {"nav"}));  // lacks arm: not a valid bid
  auctioneer.on_bid("T9", bid("erin", 0.5));           // another task: ignored
  CHECK(auctioneer.tick(100.9).empty());               // still bidding

  const auto awarded = auctioneer.tick(101.0);
  REQUIRE(awarded.size() == 1);
  CHECK(awarded[0].type == "negotiation");
  CHECK(awarded[0].payload["action"] == "award");
  CHECK(awarded[0].target == "bob");
  auctioneer.on_bid("T1", bid("frank", 0.1));  // too late
  CHECK(auctioneer.on_task_response("bob", "T1", true, 5.0, 101.2).empty());
  const json result = *auctioneer.result("T1");
  CHECK(result["state"] == "assigned");
  CHECK(result["winner"] == "bob");
  CHECK(result["estimated_time"] == 5.0);
  CHECK(result["bids"].size() == 2);
}

TEST_CASE("auctioneer: a silent winner gets 104 after bid_deadline + 2 s and the auction re-opens without it") {
  Auctioneer auctioneer;
  auctioneer.open(fetch_task(), 1.0, 100.0);
  auctioneer.on_bid("T1", bid("bob", 1.0));
  auctioneer.on_bid("T1", bid("carol", 2.0));
  REQUIRE(auctioneer.tick(101.0).at(0).target == "bob");
  CHECK(auctioneer.tick(101.0 + kWinnerGraceS).empty());  // exactly at the limit: not yet

  const auto timed_out = auctioneer.tick(101.0 + kWinnerGraceS + 0.1);
  REQUIRE(timed_out.size() == 2);
  CHECK(timed_out[0].type == "error");
  CHECK(timed_out[0].target == "bob");
  CHECK(timed_out[0].payload["code"] == 104);
  CHECK(timed_out[0].payload["task_id"] == "T1");
  CHECK(timed_out[1].type == "task_request");
  const double second_deadline = timed_out[1].payload["bid_deadline"].get<double>();
  CHECK(second_deadline == doctest::Approx(104.1));

  auctioneer.on_bid("T1", bid("bob", 0.5));  // excluded now
  auctioneer.on_bid("T1", bid("carol", 2.5));
  const auto reawarded = auctioneer.tick(second_deadline);
  REQUIRE(reawarded.size() == 1);
  CHECK(reawarded[0].target == "carol");
  auctioneer.on_task_response("carol", "T1", true, 2.5, second_deadline + 0.1);
  const json result = *auctioneer.result("T1");
  CHECK(result["state"] == "assigned");
  CHECK(result["round"] == 2);
  CHECK(result["excluded"] == json({"bob"}));
}

TEST_CASE("auctioneer: a decline or a 102 awards the next lowest; no bids ends the auction") {
  Auctioneer auctioneer;
  auctioneer.open(fetch_task(), 1.0, 0.0);
  auctioneer.on_bid("T1", bid("a", 1.0));
  auctioneer.on_bid("T1", bid("b", 2.0));
  auctioneer.on_bid("T1", bid("c", 3.0));
  auctioneer.tick(1.0);
  CHECK(auctioneer.on_task_response("b", "T1", false, std::nullopt, 1.1).empty());  // not the winner: ignored
  auto next = auctioneer.on_task_response("a", "T1", false, std::nullopt, 1.1);
  REQUIRE(next.size() == 1);
  CHECK(next[0].target == "b");
  next = auctioneer.on_error("b", "T1", 1.2);
  REQUIRE(next.size() == 1);
  CHECK(next[0].target == "c");

  Auctioneer empty;
  empty.open(fetch_task(), 1.0, 0.0);
  CHECK(empty.tick(1.0).empty());
  CHECK((*empty.result("T1"))["state"] == "no_bids");
  CHECK_FALSE(empty.result("nope"));
}

TEST_CASE("bidder: bids only with every required capability; accepts its award; a second requester gets 102") {
  Bidder bidder;
  const std::vector<std::string> caps{"nav", "arm", "teleop"};
  const CostFunction cost = [](const CostInput& input) { return 10.0 + static_cast<double>(input.queue_length); };
  const std::optional<FleetPose> here = FleetPose{};
  const Bidder::Context context{caps, cost, here, 50.0};

  TaskSpec needs_camera = fetch_task();
  needs_camera.required_capabilities.push_back("camera");
  CHECK_FALSE(bidder.on_task_request("alex", needs_camera, 51.0, context));

  const auto offer = bidder.on_task_request("alex", fetch_task(), 51.0, context);
  REQUIRE(offer);
  CHECK(offer->target == "alex");
  CHECK(offer->payload["action"] == "bid");
  CHECK(offer->payload["cost"] == 10.0);
  CHECK(bidder.on_task_request("zed", fetch_task(), 51.0, context));  // another requester, same task id

  const json header{{"source_id", "alex"}};
  const Outgoing accept = bidder.on_award("alex", "T1", header, 51.0);
  CHECK(accept.type == "task_response");
  CHECK(accept.payload["accepted"] == true);
  CHECK(accept.payload["estimated_time"] == 10.0);
  CHECK(bidder.queue_length() == 1);
  CHECK(bidder.on_award("alex", "T1", header, 51.5).payload["accepted"] == true);  // repeated: same answer

  const Outgoing second = bidder.on_award("zed", "T1", json{{"source_id", "zed"}}, 52.0);
  CHECK(second.type == "error");
  CHECK(second.payload["code"] == 102);
  CHECK(second.payload["ref"]["source_id"] == "zed");
  CHECK(second.target == "zed");

  const Outgoing unsolicited = bidder.on_award("yan", "T7", json::object(), 52.0);
  CHECK(unsolicited.payload["accepted"] == false);

  // The queue counts in the next bid's cost.
  TaskSpec other = fetch_task();
  other.task_id = "T2";
  CHECK(bidder.on_task_request("alex", other, 53.0, context)->payload["cost"] == 11.0);
  bidder.on_withdraw("alex", "T1");  // e.g. the requester timed us out (104)
  CHECK(bidder.queue_length() == 0);
}

TEST_CASE("bidder: a cost function that declines, or returns NaN, means no bid") {
  Bidder bidder;
  const std::vector<std::string> caps{"nav", "arm"};
  const std::optional<FleetPose> nowhere;
  const CostFunction decline = [](const CostInput&) { return std::optional<double>(); };
  CHECK_FALSE(bidder.on_task_request("alex", fetch_task(), 1.0, {caps, decline, nowhere, 0.0}));
  const CostFunction nan = [](const CostInput&) { return std::optional<double>(std::nan("")); };
  CHECK_FALSE(bidder.on_task_request("alex", fetch_task(), 1.0, {caps, nan, nowhere, 0.0}));
}

TEST_CASE("the default cost is nav's trip time (its TripEstimator service) from the fleet pose plus the queue") {
  const rcand::plugins::nav::TripTiming nav_trips({0.5, 0.01, 1.0});  // 0.5 m/s at full speed, 10 ms per degree at full speed
  const CostFunction cost = trip_time_cost([&nav_trips] { return &nav_trips; }, {0.5, 30.0});
  const TaskSpec task = fetch_task();  // at (3, 4): 5 m away from the origin, heading atan2(4,3) = 53.13 deg

  const double expected_turn = 53.130102354 * 0.01 / 0.5;
  const double expected_drive = 5.0 / (0.5 * 1.0 * 0.5);
  CHECK(*cost(CostInput{task, FleetPose{0, 0, 0}, 0}) == doctest::Approx(expected_turn + expected_drive).epsilon(1e-4));
  CHECK(*cost(CostInput{task, FleetPose{0, 0, 0}, 2}) == doctest::Approx(expected_turn + expected_drive + 60.0).epsilon(1e-4));
  // Already facing the location: no turn.
  CHECK(*cost(CostInput{task, FleetPose{0, 0, 53.130102354}, 0}) == doctest::Approx(expected_drive).epsilon(1e-4));
  // Nearer is cheaper.
  CHECK(*cost(CostInput{task, FleetPose{3, 3, 90}, 0}) < *cost(CostInput{task, FleetPose{0, 0, 0}, 0}));
  CHECK_FALSE(cost(CostInput{task, std::nullopt, 0}));  // no pose, a located task: cannot say
  TaskSpec anywhere = task;
  anywhere.location.reset();
  CHECK(*cost(CostInput{anywhere, std::nullopt, 1}) == 30.0);

  // Nothing offers an estimator (no nav on this robot): a located task gets no bid, the rest is priced by the queue.
  for (const TripEstimatorLookup& none : {TripEstimatorLookup{}, TripEstimatorLookup([] { return nullptr; })}) {
    const CostFunction without = trip_time_cost(none, {0.5, 30.0});
    CHECK_FALSE(without(CostInput{task, FleetPose{}, 0}));
    CHECK(*without(CostInput{anywhere, std::nullopt, 1}) == 30.0);
  }
  // An estimator that cannot say (here: a speed out of range) declines too.
  CHECK_FALSE(trip_time_cost([&nav_trips] { return &nav_trips; }, {1.5, 30.0})(CostInput{task, FleetPose{}, 0}));
}

TEST_CASE("fleet frame: the pose is rotated and moved by the origin (sdk::compose)") {
  const FleetPose p = rcand::sdk::compose(FleetPose{10.0, 5.0, 90.0}, FleetPose{1.0, 0.0, 0.0});
  CHECK(p.x_m == doctest::Approx(10.0));
  CHECK(p.y_m == doctest::Approx(6.0));
  CHECK(p.heading_deg == doctest::Approx(90.0));
  CHECK(rcand::sdk::compose(FleetPose{0, 0, 20}, FleetPose{0, 0, 170}).heading_deg == doctest::Approx(-170.0));
}

// Issue 13 #14: every table a peer can grow is bounded, with expiry.
TEST_CASE("bidder: held tasks bounded and released at expiry; far-off bids refused; pending bids bounded") {
  Bidder::Limits limits;
  limits.max_held_tasks = 3;
  limits.held_task_ttl_s = 100;
  limits.max_pending_bids = 4;
  limits.max_bid_horizon_s = 60;
  Bidder bidder(limits);
  const std::vector<std::string> caps{"teleop"};
  const CostFunction cost = [](const CostInput&) { return std::optional<double>(1.0); };
  const std::optional<FleetPose> pose;
  const Bidder::Context at_0{caps, cost, pose, 0.0};

  for (int i = 0; i < 10; ++i) {
    TaskSpec task;
    task.task_id = "D" + std::to_string(i);
    bidder.on_direct_request("flooder", task, json::object(), at_0);
  }
  CHECK(bidder.queue_length() == 3);
  TaskSpec with_deadline;
  with_deadline.task_id = "late";
  with_deadline.deadline = 50.0;
  const Outgoing declined = bidder.on_direct_request("req", with_deadline, json::object(), at_0);
  CHECK(declined.payload["accepted"] == false);
  bidder.prune(101.0);  // past the ttl: released
  CHECK(bidder.queue_length() == 0);
  CHECK(bidder.on_direct_request("req", with_deadline, json::object(), {caps, cost, pose, 101.0}).payload["accepted"] == true);
  bidder.release("late");

  // A bid_deadline further than the horizon gets no bid; the pending bids stay bounded under a flood.
  TaskSpec far;
  far.task_id = "far";
  CHECK_FALSE(bidder.on_task_request("req", far, 1e12, at_0));
  for (int i = 0; i < 100; ++i) {
    TaskSpec task;
    task.task_id = "B" + std::to_string(i);
    CHECK(bidder.on_task_request("flooder", task, 30.0, at_0));
  }
  CHECK(bidder.pending_bids() == 4);
  bidder.prune(30.0 + 61.0);  // bid_deadline + a minute
  CHECK(bidder.pending_bids() == 0);
}

TEST_CASE("auctioneer: auctions, bidders per auction and bid history are bounded") {
  Auctioneer::Limits limits;
  limits.max_auctions = 5;
  limits.max_bids_per_auction = 3;
  limits.max_history = 10;
  Auctioneer auctioneer(limits);
  for (int i = 0; i < 20; ++i) {
    TaskSpec task;
    task.task_id = "A" + std::to_string(i);
    auctioneer.open(task, 1.0, static_cast<double>(i));
  }
  CHECK(auctioneer.size() == 5);
  CHECK(auctioneer.knows("A19"));
  CHECK_FALSE(auctioneer.knows("A0"));
  for (int i = 0; i < 50; ++i) auctioneer.on_bid("A19", Bid{"bidder-" + std::to_string(i % 7), 1.0 + i, {}, 19.0});
  const json result = *auctioneer.result("A19");
  CHECK(result["bids"].size() == 10);
  std::set<std::string> bidders;
  for (const auto& bid : result["bids"]) bidders.insert(bid["bidder"].get<std::string>());
  CHECK(bidders.size() == 3);
}
