// docs/protocol.md §11.3: a message for another robot the relay knows is passed on once with the hop marker; the
// sender's own credentials decide at the target; the answer comes back through the relay; a relayed message is never
// relayed again; an unknown target is 101.
#include <doctest/doctest.h>

#include "fleet_fixture.hpp"
#include "libs/r2r_wire/message_signature.hpp"
#include "services/r2r/replay_guard.hpp"

using namespace r2r_test;
using namespace std::chrono_literals;

namespace {

const json kRelayMove = {{"type", "move"}, {"linear", 0.2}, {"angular", 0.0}, {"duration_ms", 100}};

// The messages `from` sent to `to` that carry the hop marker.
std::vector<json> relayed_copies(const Fleet& fleet, const std::string& from, const std::string& to) {
  std::vector<json> out;
  for (const auto& sent : fleet.net.log)
    if (sent.from == from && sent.to == to && sent.message["header"].contains(rcand::r2r_wire::kRelayMarker))
      out.push_back(sent.message);
  return out;
}

}  // namespace

TEST_CASE("relay: a command for a robot heard from is passed on once, marked; the target's answer comes back through it") {
  Fleet fleet;
  Robot& alex = fleet.add("alex", {"nav"}, FleetPose{});
  Robot& bob = fleet.add("bob", {"nav"}, FleetPose{});
  fleet.settle();  // status broadcasts: each has heard the other

  std::vector<json> replies;
  fleet.net.inject("alex", fleet.message("command", kRelayMove, "client", "bob").dump(), &replies);
  fleet.settle();
  CHECK(replies.empty());
  CHECK(alex.moves == 0);  // not alex's command
  REQUIRE(bob.moves == 1);
  CHECK(bob.command_principals.back() == "fleet");  // the sender's own token, not alex's authority
  const auto copies = relayed_copies(fleet, "alex", "bob");
  REQUIRE(copies.size() == 1);
  CHECK(copies[0]["header"][rcand::r2r_wire::kRelayMarker] == "alex");
  CHECK(copies[0]["header"]["source_id"] == "client");
  CHECK(copies[0]["header"]["target_id"] == "bob");
  CHECK(alex.node->counters().relayed == 1);

  // bob's answer (105: its e-stop) is addressed to the client and travels back through alex.
  bob.status.estopped = true;
  fleet.net.inject("alex", fleet.message("command", kRelayMove, "client", "bob").dump(), &replies);
  fleet.settle();
  CHECK(bob.moves == 1);
  REQUIRE(replies.size() == 1);
  CHECK(replies[0]["type"] == "error");
  CHECK(replies[0]["payload"]["code"] == 105);
  CHECK(replies[0]["header"]["source_id"] == "bob");
  CHECK(replies[0]["header"]["target_id"] == "client");
  CHECK(replies[0]["header"][rcand::r2r_wire::kRelayMarker] == "alex");
}

TEST_CASE("relay: a relayed message is never relayed again; an unknown target is 101; an error is never answered") {
  Fleet fleet;
  Robot& alex = fleet.add("alex", {"nav"}, FleetPose{});
  Robot& bob = fleet.add("bob", {"nav"}, FleetPose{});
  fleet.settle();

  std::vector<json> replies;
  json marked = fleet.message("command", kRelayMove, "client", "bob");
  marked["header"][rcand::r2r_wire::kRelayMarker] = "carol";
  fleet.net.inject("alex", marked.dump(), &replies);
  fleet.settle();
  REQUIRE(replies.size() == 1);
  CHECK(replies[0]["payload"]["code"] == 101);
  CHECK(replies[0]["payload"]["message"].get<std::string>().find("never relayed again") != std::string::npos);
  CHECK(bob.moves == 0);
  CHECK(relayed_copies(fleet, "alex", "bob").empty());

  replies.clear();
  fleet.net.inject("alex", fleet.message("command", kRelayMove, "client", "zed").dump(), &replies);
  REQUIRE(replies.size() == 1);
  CHECK(replies[0]["payload"]["code"] == 101);
  CHECK(replies[0]["payload"]["message"].get<std::string>().find("unknown target robot 'zed'") != std::string::npos);

  replies.clear();
  fleet.net.inject("alex", fleet.message("error", {{"code", 104}, {"message", "late"}}, "client", "zed").dump(), &replies);
  CHECK(replies.empty());
  CHECK(alex.node->counters().relayed == 0);
}

TEST_CASE("relay: a signed message still verifies at the target; a tampered or replayed relayed copy is refused") {
  const auto client_key = std::make_shared<const rcand::r2r_wire::Ed25519Key>(rcand::r2r_wire::Ed25519Key::generate());
  R2rSettings settings = Fleet::defaults();
  settings.auth.peers = {rcand::r2r_wire::PeerKey{"client", rcand::sdk::Role::User, client_key}};
  Fleet fleet;
  Robot& alex = fleet.add("alex", {"nav"}, FleetPose{}, settings);
  Robot& bob = fleet.add("bob", {"nav"}, FleetPose{}, settings);
  fleet.settle();

  json message = fleet.message("command", kRelayMove, "client", "bob");
  message["header"].erase("auth");
  rcand::r2r_wire::sign_message(message, "client", *client_key);
  std::vector<json> replies;
  fleet.net.inject("alex", message.dump(), &replies);
  fleet.settle();
  CHECK(replies.empty());
  REQUIRE(bob.moves == 1);
  CHECK(bob.command_principals.back() == "client");  // verified as the client's own signature
  const auto copies = relayed_copies(fleet, "alex", "bob");
  REQUIRE(copies.size() == 1);
  CHECK(copies[0]["header"]["signature"] == message["header"]["signature"]);

  // The same copy again, and the original without the marker: one message, handled once (the replay key leaves
  // the marker out).
  fleet.net.inject("bob", copies[0].dump(), &replies);
  fleet.net.inject("bob", message.dump(), &replies);
  fleet.settle();
  CHECK(bob.moves == 1);
  CHECK(replies.empty());

  // A relayed copy changed on the way: the signature no longer holds at the target.
  json tampered = copies[0];
  tampered["payload"]["linear"] = 1.0;
  fleet.net.inject("bob", tampered.dump(), &replies);
  fleet.settle();
  CHECK(bob.moves == 1);
  REQUIRE_FALSE(replies.empty());
  CHECK(replies.back()["payload"]["code"] == 103);
  CHECK(replies.back()["payload"]["message"].get<std::string>().find("bad signature") != std::string::npos);
  CHECK(alex.moves == 0);
}

TEST_CASE("relay: the hop marker is outside what a signature and the replay key cover") {
  json message{{"header", {{"version", "1.0"}, {"timestamp", 1.0}, {"source_id", "client"}}},
               {"type", "status"},
               {"payload", json::object()}};
  const std::string before = rcand::r2r_wire::signing_input(message);
  message["header"][rcand::r2r_wire::kRelayMarker] = "alex";
  CHECK(rcand::r2r_wire::signing_input(message) == before);
  const json unmarked = json::parse(message.dump());
  message["header"].erase(rcand::r2r_wire::kRelayMarker);
  CHECK(replay_key(message) == replay_key(unmarked));
}
