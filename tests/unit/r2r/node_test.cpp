#include <doctest/doctest.h>

#include "fleet_fixture.hpp"
#include "libs/r2r_wire/message_signature.hpp"

using namespace r2r_test;
using namespace std::chrono_literals;

TEST_CASE("status: sent at once, then every interval and on change; peers record it in the fleet frame") {
  Fleet fleet;
  R2rSettings shifted = Fleet::defaults();
  shifted.origin = {10.0, 5.0, 90.0};
  Robot& alex = fleet.add("alex", {"nav"}, FleetPose{1.0, 0.0, 0.0}, shifted);
  alex.status.battery = 85;
  fleet.add("bob", {"nav"}, std::nullopt);
  fleet.settle();

  const json peers = fleet["bob"].node->peers()["peers"];
  REQUIRE(peers.size() == 1);
  CHECK(peers[0]["name"] == "alex");
  const json& status = peers[0]["status"];
  CHECK(status["battery"] == 85);
  CHECK(status["position"]["x"].get<double>() == doctest::Approx(10.0));
  CHECK(status["position"]["y"].get<double>() == doctest::Approx(6.0));
  CHECK(status["position"]["heading_deg"].get<double>() == doctest::Approx(90.0));
  CHECK(status["state"] == "idle");
  CHECK(status["estopped"] == false);
  CHECK(status["capabilities"] == json({"nav"}));
  CHECK(fleet["alex"].node->peers()["peers"][0]["status"]["position"].is_null());  // bob has no pose

  const auto sent_before = fleet.net.sent("status", "alex").size();
  fleet.advance(500ms);
  CHECK(fleet.net.sent("status", "alex").size() == sent_before);  // unchanged, interval not reached
  alex.status.estopped = true;
  alex.status.state = "estop";
  fleet.advance(250ms);  // a change goes out before the interval
  CHECK(fleet.net.sent("status", "alex").size() == sent_before + 1);
  CHECK(fleet["bob"].node->peers()["peers"][0]["status"]["estopped"] == true);
  fleet.advance(1000ms);  // the interval, unchanged
  CHECK(fleet.net.sent("status", "alex").size() == sent_before + 2);
}

TEST_CASE("task_request / task_response / negotiation / error round-trip, and subscribers see them") {
  Fleet fleet;
  Robot& alex = fleet.add("alex", {"nav"}, FleetPose{});
  Robot& bob = fleet.add("bob", {"nav", "arm"}, FleetPose{});
  std::vector<ReceivedMessage> alex_saw;
  for (auto type : {rcand::r2r_wire::MessageType::TaskResponse, rcand::r2r_wire::MessageType::Negotiation,
                    rcand::r2r_wire::MessageType::Error})
    alex.node->subscribe(type, [&](const ReceivedMessage& m) { alex_saw.push_back(m); });
  std::vector<ReceivedMessage> bob_saw;
  bob.node->subscribe(rcand::r2r_wire::MessageType::TaskRequest, [&](const ReceivedMessage& m) { bob_saw.push_back(m); });

  // A direct request (no bid_deadline) is answered with task_response.
  REQUIRE(std::holds_alternative<std::string>(
      alex.node->send(rcand::r2r_wire::MessageType::TaskRequest,
                      {{"task_id", "T1"}, {"description", "pick"}, {"required_capabilities", {"arm"}}}, "bob")));
  fleet.settle();
  REQUIRE(bob_saw.size() == 1);
  CHECK(bob_saw[0].envelope.payload["task_id"] == "T1");
  CHECK(bob_saw[0].principal == "fleet");
  const auto responses = fleet.net.sent("task_response", "bob", "alex");
  REQUIRE(responses.size() == 1);
  CHECK(responses[0].message["payload"]["accepted"] == true);
  CHECK(responses[0].message["payload"]["estimated_time"] == 0.0);
  CHECK(bob.fleet->held_tasks().size() == 1);  // the fleet plugin's bidder answered

  alex.node->send(rcand::r2r_wire::MessageType::Negotiation, {{"task_id", "T1"}, {"action", "withdraw"}}, "bob");
  bob.node->send(rcand::r2r_wire::MessageType::Error, {{"code", 104}, {"message", "late"}}, "alex");
  fleet.settle();
  CHECK(bob.fleet->held_tasks().empty());  // withdrawn by its requester
  REQUIRE(alex_saw.size() == 2);
  CHECK(alex_saw[0].envelope.type == rcand::r2r_wire::MessageType::TaskResponse);
  CHECK(alex_saw[1].envelope.type == rcand::r2r_wire::MessageType::Error);
  CHECK(alex_saw[1].envelope.payload["code"] == 104);
  CHECK(fleet.net.sent("error", "alex").empty());  // an error is never answered with an error

  // A capability this robot lacks: declined.
  alex.node->send(rcand::r2r_wire::MessageType::TaskRequest, {{"task_id", "T2"}, {"required_capabilities", {"camera"}}}, "bob");
  fleet.settle();
  CHECK(fleet.net.sent("task_response", "bob", "alex").back().message["payload"]["accepted"] == false);

  // A payload that does not fit its type is refused before it is sent.
  const auto bad = alex.node->send(rcand::r2r_wire::MessageType::Negotiation, {{"task_id", "T1"}, {"action", "haggle"}}, "bob");
  REQUIRE(std::holds_alternative<rcand::r2r_wire::R2rError>(bad));
  CHECK(std::get<rcand::r2r_wire::R2rError>(bad).field == "/payload/action");
}

TEST_CASE("command: runs through the action route as the sender; e-stopped answers 105 and nothing moves") {
  Fleet fleet;
  Robot& alex = fleet.add("alex", {"teleop"}, std::nullopt);
  Robot& bob = fleet.add("bob", {"teleop"}, std::nullopt);
  const json move{{"type", "move"}, {"linear", 0.3}, {"duration_ms", 200}};

  alex.node->send(rcand::r2r_wire::MessageType::Command, move, "bob");
  fleet.settle();
  CHECK(bob.moves == 1);
  CHECK(bob.command_principals == std::vector<std::string>{"fleet"});
  CHECK(fleet.net.sent("error", "bob").empty());

  bob.status.estopped = true;
  alex.node->send(rcand::r2r_wire::MessageType::Command, move, "bob");
  fleet.settle();
  CHECK(bob.moves == 1);
  const auto errors = fleet.net.sent("error", "bob", "alex");
  REQUIRE(errors.size() == 1);
  CHECK(errors[0].message["payload"]["code"] == 105);
  CHECK(errors[0].message["payload"]["ref"]["source_id"] == "alex");
  CHECK(errors[0].message["payload"]["http_status"] == 423);

  // A guest's token cannot command: 103 before the action route is reached.
  bob.status.estopped = false;
  json guest = fleet.message("command", move, "alex", "bob");
  guest["header"]["auth"]["token"] = kViewerToken;
  std::vector<json> replies;
  fleet.net.inject("bob", guest.dump(), &replies);
  CHECK(bob.moves == 1);
  REQUIRE(replies.size() == 1);
  CHECK(replies[0]["payload"]["code"] == 103);
  CHECK_FALSE(replies[0]["payload"]["ref"].contains("auth"));  // the token is never echoed
}

namespace {
// A fleet e-stop from "alex" with a guest's token (scope status, as POST /api/stop).
json guest_estop(Fleet& fleet) {
  json stop = fleet.message("command", {{"type", "estop"}, {"reason", "aisle 3"}}, "alex");
  stop["header"]["auth"]["token"] = kViewerToken;
  return stop;
}
}  // namespace

TEST_CASE("fleet e-stop: a command {type: estop} needs scope status, latches as the sender, status goes out at once") {
  Fleet fleet;
  Robot& bob = fleet.add("bob", {"teleop"}, std::nullopt);
  fleet.settle();
  const std::size_t statuses = fleet.net.sent("status", "bob").size();
  // A guest may stop the robot; no tick runs between the stop and its status.
  const json stop = guest_estop(fleet);
  std::vector<json> replies;
  fleet.net.inject("bob", stop.dump(), &replies);
  REQUIRE(bob.stops.size() == 1);
  CHECK(bob.stops[0]["principal"] == "viewer");
  CHECK(bob.stops[0]["body"] == json{{"reason", "fleet e-stop from 'alex': aisle 3"}, {"from", "r2r alex"}});
  CHECK(replies.empty());
  fleet.net.pump();  // the queued messages go out; the nodes do not tick
  const auto sent = fleet.net.sent("status", "bob");
  REQUIRE(sent.size() == statuses + 1);
  CHECK(sent.back().message["payload"]["estopped"] == true);
  CHECK(bob.moves == 0);  // never the action route

  // Never refused while latched; a reason that is not text is a malformed message (100), nothing latches.
  fleet.net.inject("bob", stop.dump(), &replies);
  CHECK(bob.stops.size() == 2);
  json bad = fleet.message("command", {{"type", "estop"}, {"reason", 7}}, "alex");
  bad["header"]["auth"]["token"] = kViewerToken;
  fleet.net.inject("bob", bad.dump(), &replies);
  CHECK(bob.stops.size() == 2);
  REQUIRE(replies.size() == 1);
  CHECK(replies[0]["payload"]["code"] == 100);
}

TEST_CASE("fleet e-stop: the latched status is what follows the latch (after_stop), never ahead of it") {
  Fleet fleet;
  Robot& bob = fleet.add("bob", {"teleop"}, std::nullopt);
  bob.defer_after_stop = true;  // as rcand's clock thread, which runs it once the stops on the machine's cores ran
  fleet.settle();
  const std::size_t statuses = fleet.net.sent("status", "bob").size();
  std::vector<json> replies;
  fleet.net.inject("bob", guest_estop(fleet).dump(), &replies);
  CHECK(bob.stops.size() == 1);  // latched on the receiving thread
  fleet.net.pump();
  CHECK(fleet.net.sent("status", "bob").size() == statuses);
  REQUIRE(bob.after_stop_work.size() == 1);
  bob.after_stop_work.front()();
  fleet.net.pump();
  const auto sent = fleet.net.sent("status", "bob");
  REQUIRE(sent.size() == statuses + 1);
  CHECK(sent.back().message["payload"]["estopped"] == true);
}

TEST_CASE("bad messages: 100 (malformed, unknown type), 101 (unknown target), 103 (wrong token); none reach subscribers") {
  Fleet fleet;
  Robot& bob = fleet.add("bob", {"nav"}, std::nullopt);
  int seen = 0;
  for (auto type :
       {rcand::r2r_wire::MessageType::Status, rcand::r2r_wire::MessageType::Command, rcand::r2r_wire::MessageType::TaskRequest})
    bob.node->subscribe(type, [&](const ReceivedMessage&) { ++seen; });

  std::vector<json> replies;
  fleet.net.inject("bob", "{not json", &replies);
  REQUIRE(replies.size() == 1);
  CHECK(replies[0]["type"] == "error");
  CHECK(replies[0]["payload"]["code"] == 100);
  CHECK(replies[0]["header"]["source_id"] == "bob");
  CHECK_FALSE(replies[0]["header"].contains("target_id"));  // nobody to name: answered on the connection only

  replies.clear();
  fleet.net.inject("bob", fleet.message("teleport", json::object()).dump(), &replies);
  REQUIRE(replies.size() == 1);
  CHECK(replies[0]["payload"]["code"] == 100);
  CHECK(replies[0]["header"]["target_id"] == "outsider");
  CHECK(replies[0]["payload"]["field"] == "/type");

  replies.clear();
  fleet.net.inject("bob", fleet.message("status", {{"battery", 50}}, "outsider", "zed").dump(), &replies);
  REQUIRE(replies.size() == 1);
  CHECK(replies[0]["payload"]["code"] == 101);

  replies.clear();  // the RURI is an alias of the name
  fleet.net.inject("bob", fleet.message("status", {{"battery", 50}}, "outsider", "rcan://acme.rover.bob").dump(), &replies);
  CHECK(replies.empty());
  CHECK(seen == 1);

  replies.clear();
  json wrong = fleet.message("status", {{"battery", 50}});
  wrong["header"]["auth"]["token"] = "guessed";
  fleet.net.inject("bob", wrong.dump(), &replies);
  REQUIRE(replies.size() == 1);
  CHECK(replies[0]["payload"]["code"] == 103);
  CHECK(replies[0].dump().find("guessed") == std::string::npos);

  replies.clear();  // never answer an error, even a malformed one; never answer ourselves
  fleet.net.inject("bob", fleet.message("error", {{"code", "x"}}).dump(), &replies);
  fleet.net.inject("bob", fleet.message("error", {{"code", 100}, {"message", "m"}}, "outsider", "zed").dump(), &replies);
  fleet.net.inject("bob", fleet.message("status", {{"battery", 500}}, "bob").dump(), &replies);
  CHECK(replies.empty());
  CHECK(seen == 1);
  CHECK(bob.node->counters().rejected >= 6);
}

TEST_CASE("auction: the nearest capable robot wins; one without the capability does not bid") {
  Fleet fleet;
  Robot& alex = fleet.add("alex", {"nav"}, FleetPose{});  // the requester
  fleet.add("bob", {"nav", "arm"}, FleetPose{4.0, 0.0, 0.0});
  fleet.add("carol", {"nav", "arm"}, FleetPose{-5.0, -5.0, 0.0});
  fleet.add("dave", {"nav"}, FleetPose{5.0, 0.0, 0.0});  // nearest, but no arm
  fleet.settle();

  TaskSpec task;
  task.task_id = "fetch-1";
  task.required_capabilities = {"nav", "arm"};
  task.location = FleetPoint{5.0, 0.0};
  REQUIRE(std::get<std::string>(alex.fleet->open_auction(task)) == "fetch-1");
  fleet.settle();
  CHECK(fleet.net.sent("negotiation", "dave").empty());
  CHECK((*alex.fleet->auction_result("fetch-1"))["state"] == "bidding");

  fleet.advance(1000ms);  // the bid deadline
  const json result = *alex.fleet->auction_result("fetch-1");
  CHECK(result["state"] == "assigned");
  CHECK(result["winner"] == "bob");
  REQUIRE(result["bids"].size() == 2);
  double bob_cost = 0, carol_cost = 0;
  for (const auto& bid : result["bids"]) (bid["bidder"] == "bob" ? bob_cost : carol_cost) = bid["cost"].get<double>();
  CHECK(bob_cost == doctest::Approx(1.0 / 0.25));  // 1 m at 0.25 m/s, no turn
  CHECK(carol_cost > bob_cost);
  CHECK(result["estimated_time"].get<double>() == doctest::Approx(bob_cost));
  CHECK(fleet["bob"].fleet->held_tasks()[0]["task_id"] == "fetch-1");
  CHECK(fleet["carol"].fleet->held_tasks().empty());

  // Generated task ids are unique.
  const auto first = std::get<std::string>(alex.fleet->open_auction(TaskSpec{}));
  const auto second = std::get<std::string>(alex.fleet->open_auction(TaskSpec{}));
  CHECK(first != second);
}

TEST_CASE("auction: a second award for a task already held from another requester gets 102") {
  Fleet fleet;
  Robot& alex = fleet.add("alex", {"nav"}, FleetPose{});
  Robot& zed = fleet.add("zed", {"nav"}, FleetPose{});
  Robot& bob = fleet.add("bob", {"nav", "arm"}, FleetPose{1.0, 0.0, 0.0});
  TaskSpec task;
  task.task_id = "shared-id";
  task.required_capabilities = {"arm"};
  alex.fleet->open_auction(task);
  zed.fleet->open_auction(task);
  fleet.settle();
  fleet.advance(1000ms);

  const auto refusals = fleet.net.sent("error", "bob", "zed");
  const auto to_alex = fleet.net.sent("error", "bob", "alex");
  // Exactly one requester got the task; the other got 102.
  REQUIRE(refusals.size() + to_alex.size() == 1);
  const auto& refusal = refusals.empty() ? to_alex[0] : refusals[0];
  CHECK(refusal.message["payload"]["code"] == 102);
  CHECK(refusal.message["payload"]["task_id"] == "shared-id");
  CHECK(bob.fleet->held_tasks().size() == 1);
  Robot& loser = refusals.empty() ? alex : zed;
  Robot& winner = refusals.empty() ? zed : alex;
  CHECK((*winner.fleet->auction_result("shared-id"))["state"] == "assigned");
  fleet.advance(1000ms);  // the loser re-opened; bob holds the task elsewhere and does not bid again
  CHECK((*loser.fleet->auction_result("shared-id"))["state"] == "no_bids");
}

TEST_CASE("auction: a winner silent past bid_deadline + 2 s gets 104 and the task is re-awarded") {
  Fleet fleet;
  Robot& alex = fleet.add("alex", {"nav"}, FleetPose{});
  Robot& bob = fleet.add("bob", {"nav", "arm"}, FleetPose{1.0, 0.0, 0.0});
  Robot& carol = fleet.add("carol", {"nav", "arm"}, FleetPose{3.0, 0.0, 0.0});
  TaskSpec task;
  task.task_id = "T-silent";
  task.required_capabilities = {"arm"};
  task.location = FleetPoint{0.0, 0.0};
  alex.fleet->open_auction(task);
  fleet.settle();                          // bids are in
  fleet.net.endpoint("bob").muted = true;  // bob goes silent before the award
  fleet.advance(1000ms);
  CHECK((*alex.fleet->auction_result("T-silent"))["state"] == "awarded");
  CHECK((*alex.fleet->auction_result("T-silent"))["winner"] == "bob");

  fleet.advance(2000ms);  // exactly bid_deadline + 2 s: still waiting
  CHECK(fleet.net.sent("error", "alex", "bob").empty());
  fleet.advance(100ms);
  const auto timeouts = fleet.net.sent("error", "alex", "bob");
  REQUIRE(timeouts.size() == 1);
  CHECK(timeouts[0].message["payload"]["code"] == 104);
  CHECK(bob.fleet->held_tasks().empty());  // bob heard the 104 and let the task go

  fleet.advance(1000ms);  // the second round's deadline
  const json result = *alex.fleet->auction_result("T-silent");
  CHECK(result["state"] == "assigned");
  CHECK(result["winner"] == "carol");
  CHECK(result["round"] == 2);
  CHECK(result["excluded"] == json({"bob"}));
  CHECK(carol.fleet->held_tasks().size() == 1);
}

TEST_CASE("a plugin's cost function replaces the default (R2rLink::set_cost_function, handed on to the fleet plugin)") {
  Fleet fleet;
  Robot& alex = fleet.add("alex", {"nav"}, FleetPose{});
  Robot& bob = fleet.add("bob", {"nav"}, FleetPose{});
  fleet.add("carol", {"nav"}, FleetPose{});
  // Another plugin on bob prices bids through its own link, as a vendor plugin would.
  auto vendor = bob.bridge->make_link(*bob.worker, "com.acme.pricing (pricing)");
  vendor->set_cost_function([](const json&, const std::optional<rcand::sdk::R2rPose>&, std::size_t) { return 0.5; });
  TaskSpec task;
  task.task_id = "T";
  task.location = FleetPoint{5.0, 0.0};  // 20 s away for everyone by the default
  alex.fleet->open_auction(task);
  fleet.settle();
  fleet.advance(1000ms);
  CHECK((*alex.fleet->auction_result("T"))["winner"] == "bob");
  vendor->set_cost_function({});  // back to the default: bob's queue (one task) now costs 30 s more
  task.task_id = "T2";
  alex.fleet->open_auction(task);
  fleet.settle();
  fleet.advance(1000ms);
  CHECK((*alex.fleet->auction_result("T2"))["winner"] == "carol");
}

TEST_CASE("signed fleet: signed messages flow; unsigned, unknown-key and replayed ones get 103") {
  Fleet fleet;
  auto alex_key = std::make_shared<const rcand::r2r_wire::Ed25519Key>(rcand::r2r_wire::Ed25519Key::generate());
  auto bob_key = std::make_shared<const rcand::r2r_wire::Ed25519Key>(rcand::r2r_wire::Ed25519Key::generate());
  auto settings_for = [&](std::shared_ptr<const rcand::r2r_wire::Ed25519Key> own, const std::string& peer_name,
                          const std::shared_ptr<const rcand::r2r_wire::Ed25519Key>& peer_key) {
    R2rSettings s = Fleet::defaults();
    s.outbound_token.reset();  // signatures only
    s.private_key = std::move(own);
    s.auth.require_signatures = true;
    s.auth.peers.push_back({peer_name, rcand::sdk::Role::User,
                            std::make_shared<const rcand::r2r_wire::Ed25519Key>(
                                rcand::r2r_wire::Ed25519Key::public_from_text(peer_key->public_base64()))});
    return s;
  };
  Robot& alex = fleet.add("alex", {"nav"}, FleetPose{}, settings_for(alex_key, "bob", bob_key));
  Robot& bob = fleet.add("bob", {"teleop"}, FleetPose{}, settings_for(bob_key, "alex", alex_key));
  fleet.settle();
  CHECK(alex.node->peers()["peers"].size() == 1);
  CHECK(bob.node->peers()["peers"].size() == 1);
  const auto status = fleet.net.sent("status", "alex");
  REQUIRE_FALSE(status.empty());
  CHECK(status[0].message["header"]["signature"]["key_id"] == "alex");
  CHECK_FALSE(status[0].message["header"].contains("auth"));

  alex.node->send(rcand::r2r_wire::MessageType::Command, {{"type", "move"}, {"linear", 0.1}}, "bob");
  fleet.settle();
  CHECK(bob.moves == 1);
  CHECK(bob.command_principals == std::vector<std::string>{"alex"});

  std::vector<json> replies;
  fleet.net.inject("bob", fleet.message("command", {{"type", "move"}}, "alex", "bob").dump(), &replies);  // token, no signature
  REQUIRE(replies.size() == 1);
  CHECK(replies[0]["payload"]["code"] == 103);
  CHECK(replies[0]["header"]["signature"]["key_id"] == "bob");  // errors are signed too

  json foreign = fleet.message("command", {{"type", "move"}}, "mallory", "bob");
  rcand::r2r_wire::sign_message(foreign, "mallory", rcand::r2r_wire::Ed25519Key::generate());
  replies.clear();
  fleet.net.inject("bob", foreign.dump(), &replies);
  REQUIRE(replies.size() == 1);
  CHECK(replies[0]["payload"]["code"] == 103);

  // Alex's real command, captured and replayed: inside the window it is dropped as a copy, after it refused as stale.
  const auto sent = fleet.net.sent("command", "alex");
  REQUIRE(sent.size() == 1);
  replies.clear();
  fleet.net.inject("bob", sent[0].message.dump(), &replies);
  CHECK(replies.empty());
  CHECK(bob.moves == 1);
  fleet.clock.advance(std::chrono::seconds(31));
  replies.clear();
  fleet.net.inject("bob", sent[0].message.dump(), &replies);
  REQUIRE(replies.size() == 1);
  CHECK(replies[0]["payload"]["code"] == 103);
  CHECK(replies[0]["payload"]["message"].get<std::string>().find("stale") != std::string::npos);
  CHECK(bob.moves == 1);
}
