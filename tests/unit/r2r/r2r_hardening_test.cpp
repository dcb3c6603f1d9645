// Issue 13 (#9, #10, #14): signed-message replays under other spellings and across a restart, the bearer token kept
// off UDP and MQTT, and the peer table bounded with expiry. The auction's bounds (held tasks, pending bids, auctions)
// are tested with its logic in plugins/fleet/auction_test.cpp.
#include <doctest/doctest.h>

#include <chrono>
#include <memory>
#include <string>
#include <vector>

#include "fleet_fixture.hpp"
#include "libs/r2r_wire/message_signature.hpp"
#include "libs/rcan/base64.hpp"
#include "services/r2r/replay_guard.hpp"

using namespace r2r_test;
using namespace std::chrono_literals;

namespace {

// A transport that records what it was handed, under the name of a real one ("udp", "mqtt", "ws").
class HardeningRecordingTransport final : public Transport {
 public:
  explicit HardeningRecordingTransport(std::string name) : name_(std::move(name)) {}
  std::string_view name() const noexcept override { return name_; }
  void start(Deliver deliver) override { deliver_ = std::move(deliver); }
  bool send(const std::string& bytes, const std::optional<std::string>&) override {
    sent.push_back(bytes);
    return true;
  }
  void stop() noexcept override { deliver_ = nullptr; }
  std::vector<std::string> sent;

 private:
  std::string name_;
  Deliver deliver_;
};

// The signed settings of a two-robot fleet: `own` signs, `peer_name` is accepted with `peer_key`.
R2rSettings hardening_signed_settings(std::shared_ptr<const rcand::r2r_wire::Ed25519Key> own, const std::string& peer_name,
                                      const std::shared_ptr<const rcand::r2r_wire::Ed25519Key>& peer_key) {
  R2rSettings s = Fleet::defaults();
  s.outbound_token.reset();
  s.private_key = std::move(own);
  s.auth.require_signatures = true;
  s.auth.peers.push_back({peer_name, rcand::sdk::Role::User,
                          std::make_shared<const rcand::r2r_wire::Ed25519Key>(
                              rcand::r2r_wire::Ed25519Key::public_from_text(peer_key->public_base64()))});
  return s;
}

// Every other spelling of the base64 text `canonical` that a lax decoder maps to the same bytes.
std::vector<std::string> hardening_sig_spellings(const std::string& canonical) {
  std::vector<std::string> out;
  REQUIRE(canonical.size() >= 4);
  REQUIRE(canonical.ends_with("=="));  // 64 bytes: one byte in the last group, 4 unused bits in its second symbol
  const std::string alphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  const std::size_t last = canonical.size() - 3;
  const auto value = alphabet.find(canonical[last]);
  for (std::size_t low = 1; low < 16; low += 5) {  // the unused bits set: 3 variants
    std::string variant = canonical;
    variant[last] = alphabet[(value & ~std::size_t{15}) | low];
    out.push_back(variant);
  }
  out.push_back(canonical.substr(0, canonical.size() - 2));  // padding left off
  out.push_back(canonical + "\n");                           // whitespace
  out.push_back(" " + canonical);
  std::string urlsafe = canonical;
  for (char& c : urlsafe) c = c == '+' ? '-' : c == '/' ? '_' : c;
  if (urlsafe != canonical) out.push_back(urlsafe);
  return out;
}

}  // namespace

TEST_CASE("base64: only the canonical spelling decodes (unused bits, padding, whitespace, url-safe alphabet)") {
  const std::string bytes(64, '\x5a');
  const std::string canonical = base64_encode(bytes);
  REQUIRE(base64_decode(canonical) == bytes);
  for (const std::string& variant : hardening_sig_spellings(canonical)) {
    INFO("variant: " << variant);
    CHECK_FALSE(base64_decode(variant));
  }
  CHECK(base64_decode("QQ==") == std::string("A"));  // "QR==" sets an unused bit
  CHECK_FALSE(base64_decode("QR=="));
  CHECK_FALSE(
      base64_decode("QUI="
                    "x"));
  CHECK(base64_decode("QUI=") == std::string("AB"));
  CHECK_FALSE(base64_decode("QUJ="));  // "AB" with an unused bit set
  CHECK_FALSE(base64_decode("QUI"));
  CHECK_FALSE(base64_decode("Q==="));
  CHECK_FALSE(base64_decode("-_-_"));
  CHECK(base64_decode("") == std::string());
}

TEST_CASE("replay key: one key per signed message whatever its spelling; different messages differ") {
  json message{{"header", {{"version", "1.0"}, {"timestamp", 1700000000.5}, {"source_id", "alex"}}},
               {"type", "command"},
               {"payload", {{"type", "move"}, {"linear", 0.1}}}};
  const std::string key = replay_key(message);
  CHECK(key.size() == 32);
  json respelled = json::parse(R"({"payload":{"linear":1e-1,"type":"move"}, "type":"command",
      "header":{"source_id":"alex","timestamp":1.7000000005e9,"version":"1.0"}})");
  CHECK(replay_key(respelled) == key);
  respelled["header"]["signature"] = {{"key_id", "alex"}, {"sig", "anything"}};  // not part of the signed input
  CHECK(replay_key(respelled) == key);
  message["payload"]["linear"] = 0.2;
  CHECK(replay_key(message) != key);

  ReplayGuard guard(35.0);
  CHECK(guard.first_time(key, 100.0));
  CHECK_FALSE(guard.first_time(key, 101.0));
  CHECK(guard.first_time(key, 200.0));  // long forgotten: the timestamp check refuses such a copy anyway
}

TEST_CASE("signed replay: a captured command under 5 other spellings moves once; a signature re-spelled is refused") {
  Fleet fleet;
  auto alex_key = std::make_shared<const rcand::r2r_wire::Ed25519Key>(rcand::r2r_wire::Ed25519Key::generate());
  auto bob_key = std::make_shared<const rcand::r2r_wire::Ed25519Key>(rcand::r2r_wire::Ed25519Key::generate());
  fleet.add("alex", {"nav"}, FleetPose{}, hardening_signed_settings(alex_key, "bob", bob_key));
  Robot& bob = fleet.add("bob", {"teleop"}, FleetPose{}, hardening_signed_settings(bob_key, "alex", alex_key));
  fleet.advance(10ms);  // after both started
  fleet["alex"].node->send(rcand::r2r_wire::MessageType::Command, {{"type", "move"}, {"linear", 0.1}}, "bob");
  fleet.settle();
  REQUIRE(bob.moves == 1);
  const auto captured = fleet.net.sent("command", "alex");
  REQUIRE(captured.size() == 1);
  const json original = captured[0].message;
  const std::string sig = original["header"]["signature"]["sig"];

  // Five other spellings of the signature: each decodes (laxly) to the same 64 bytes.
  int refused = 0;
  for (const std::string& variant : hardening_sig_spellings(sig)) {
    json copy = original;
    copy["header"]["signature"]["sig"] = variant;
    std::vector<json> replies;
    fleet.net.inject("bob", copy.dump(), &replies);
    if (!replies.empty() && replies[0]["payload"]["code"] == 103) ++refused;
  }
  CHECK(refused >= 5);
  // Other spellings of the message itself (whitespace, key order, number forms) with the right signature: copies.
  const std::string respelled[] = {
      original.dump(2), " " + original.dump() + "\n",
      R"({"payload":)" + original["payload"].dump() + R"(,"type":"command","header":)" + original["header"].dump() + "}"};
  for (const std::string& text : respelled) {
    std::vector<json> replies;
    fleet.net.inject("bob", text, &replies);
    CHECK(replies.empty());  // dropped silently as a copy
  }
  CHECK(bob.moves == 1);
}

TEST_CASE("signed replay across a restart: a message signed before the robot started is refused (103), nothing moves") {
  Fleet fleet;
  auto alex_key = std::make_shared<const rcand::r2r_wire::Ed25519Key>(rcand::r2r_wire::Ed25519Key::generate());
  auto bob_key = std::make_shared<const rcand::r2r_wire::Ed25519Key>(rcand::r2r_wire::Ed25519Key::generate());
  fleet.add("alex", {"nav"}, FleetPose{}, hardening_signed_settings(alex_key, "bob", bob_key));
  Robot& bob = fleet.add("bob", {"teleop"}, FleetPose{}, hardening_signed_settings(bob_key, "alex", alex_key));
  fleet.advance(10ms);
  fleet["alex"].node->send(rcand::r2r_wire::MessageType::Command, {{"type", "move"}, {"linear", 0.1}}, "bob");
  fleet.settle();
  REQUIRE(bob.moves == 1);
  const json captured = fleet.net.sent("command", "alex").at(0).message;

  // bob restarts 2 s later (a new node: its replay memory is empty), well inside the 30 s replay window.
  fleet.clock.advance(2s);
  Robot& restarted = fleet.add("bob-restarted", {"teleop"}, FleetPose{}, hardening_signed_settings(bob_key, "alex", alex_key));
  json retargeted = captured;  // the same capture, as the restarted robot sees it (it answers to its own name)
  retargeted["header"]["target_id"] = "bob-restarted";
  rcand::r2r_wire::sign_message(retargeted, "alex", *alex_key);  // still timestamped before the restart
  std::vector<json> replies;
  fleet.net.inject("bob-restarted", retargeted.dump(), &replies);
  REQUIRE(replies.size() == 1);
  CHECK(replies[0]["payload"]["code"] == 103);
  CHECK(replies[0]["payload"]["message"].get<std::string>().find("before this robot started") != std::string::npos);
  CHECK(restarted.moves == 0);

  // A message signed after the restart goes through.
  json fresh = captured;
  fresh["header"]["target_id"] = "bob-restarted";
  fresh["header"]["timestamp"] = fleet.clock.wall_ms() / 1000.0;
  rcand::r2r_wire::sign_message(fresh, "alex", *alex_key);
  replies.clear();
  fleet.net.inject("bob-restarted", fresh.dump(), &replies);
  CHECK(replies.empty());
  CHECK(restarted.moves == 1);
}

TEST_CASE("token: header.auth.token goes over WebSocket only, never over UDP or MQTT; signatures go everywhere") {
  Fleet fleet;
  HardeningRecordingTransport udp("udp"), mqtt("mqtt"), ws("ws");
  R2rSettings settings = Fleet::defaults();  // with the fleet token
  settings.private_key = std::make_shared<const rcand::r2r_wire::Ed25519Key>(rcand::r2r_wire::Ed25519Key::generate());
  Robot& alex = fleet.add("alex", {"nav"}, FleetPose{}, settings);
  alex.node->stop();
  alex.node->add_transport(&udp);
  alex.node->add_transport(&mqtt);
  alex.node->add_transport(&ws);
  alex.node->start();
  fleet.advance(1500ms);                                                              // status (broadcast) at least once more
  alex.node->send(rcand::r2r_wire::MessageType::Command, {{"type", "move"}}, "bob");  // targeted
  alex.node->send(rcand::r2r_wire::MessageType::TaskRequest, {{"task_id", "T"}, {"bid_deadline", 1e9}}, std::nullopt);
  alex.node->stop();

  REQUIRE_FALSE(udp.sent.empty());
  REQUIRE_FALSE(mqtt.sent.empty());
  for (const auto* transport : {&udp, &mqtt}) {
    for (const std::string& bytes : transport->sent) {
      INFO(transport->name() << ": " << bytes);
      CHECK(bytes.find(kFleetToken) == std::string::npos);
      const json message = json::parse(bytes);
      CHECK_FALSE(message["header"].contains("auth"));
      CHECK(message["header"]["signature"]["key_id"] == "alex");
    }
  }
  REQUIRE_FALSE(ws.sent.empty());
  for (const std::string& bytes : ws.sent) CHECK(json::parse(bytes)["header"]["auth"]["token"] == kFleetToken);

  // send_message says which transports took it.
  alex.node->start();
  const auto outcome = alex.node->send_message(rcand::r2r_wire::MessageType::Status, {{"battery", 50}}, std::nullopt);
  REQUIRE(std::holds_alternative<SendOutcome>(outcome));
  const auto& queued_on = std::get<SendOutcome>(outcome).queued_on;
  CHECK(std::find(queued_on.begin(), queued_on.end(), "udp") != queued_on.end());
  CHECK(std::get<SendOutcome>(outcome).bytes.find(kFleetToken) == std::string::npos);
  alex.node->stop();
}

TEST_CASE("peers: the table holds at most max_peers, keeps only bounded status fields and forgets silent peers") {
  Fleet fleet;
  R2rSettings settings = Fleet::defaults();
  settings.max_peers = 8;
  settings.peer_expiry_s = 5;
  Robot& bob = fleet.add("bob", {"teleop"}, FleetPose{}, settings);
  for (int i = 0; i < 50; ++i) {
    json status{{"battery", 50},
                {"state", std::string(5000, 's')},
                {"capabilities", std::vector<std::string>(150, std::string(300, 'c'))},
                {"pad", std::string(10000, 'x')}};
    fleet.net.inject("bob", fleet.message("status", status, "guest-" + std::to_string(i)).dump());
    fleet.clock.advance(1ms);
  }
  json doc = bob.node->peers();
  REQUIRE(doc["peers"].size() == 8);
  CHECK(doc["peers"][0]["name"].get<std::string>().starts_with("guest-4"));  // the most recently heard stayed
  CHECK(doc.dump().size() < 8 * 6000);
  CHECK_FALSE(doc["peers"][0]["status"].contains("pad"));
  CHECK(doc["peers"][0]["status"]["capabilities"].size() <= 64);
  CHECK(doc["peers"][0]["status"]["battery"] == 50);

  fleet.advance(3s);
  fleet.net.inject("bob", fleet.message("status", {{"battery", 1}}, "steady").dump());
  fleet.advance(3s);  // the guests: 6 s silent, beyond peer_expiry_s; "steady": 3 s
  doc = bob.node->peers();
  REQUIRE(doc["peers"].size() == 1);
  CHECK(doc["peers"][0]["name"] == "steady");
}

TEST_CASE("settings: max_peers, peer_expiry_s and max_held_tasks are read and checked") {
  const json block{{"max_peers", 16}, {"peer_expiry_s", 9.5}, {"max_held_tasks", 2}};
  const auto s = load_r2r_settings(block, ".");
  CHECK(s.max_peers == 16);
  CHECK(s.peer_expiry_s == 9.5);
  // max_held_tasks bounds the fleet plugin's bidder, which reads it from the robot config; the R2R key table checks it.
  using rcand::plugins::fleet::read_fleet_settings;
  CHECK(read_fleet_settings(rcand::sdk::ConfigView(json{{"runtime", {{"r2r", block}}}})).bidder.max_held_tasks == 2);
  const auto defaults = load_r2r_settings(json::object(), ".");
  CHECK(defaults.max_peers == 1024);
  CHECK(defaults.peer_expiry_s == 120.0);
  CHECK(read_fleet_settings(rcand::sdk::ConfigView(json::object())).bidder.max_held_tasks == 64);
  CHECK_THROWS_WITH_AS(load_r2r_settings(json{{"max_held_tasks", 0}}, "."), doctest::Contains("runtime.r2r.max_held_tasks"),
                       std::invalid_argument);
  CHECK_THROWS_WITH_AS(load_r2r_settings(json{{"max_peers", 0}}, "."), doctest::Contains("runtime.r2r.max_peers"),
                       std::invalid_argument);
  CHECK_THROWS_WITH_AS(load_r2r_settings(json{{"peer_expiry_s", -1}}, "."), doctest::Contains("runtime.r2r.peer_expiry_s"),
                       std::invalid_argument);
}

TEST_CASE("status topic: a signed offline status hours old counts only from its sender's own topic; a stale live one never") {
  Fleet fleet;
  auto alex_key = std::make_shared<const rcand::r2r_wire::Ed25519Key>(rcand::r2r_wire::Ed25519Key::generate());
  auto bob_key = std::make_shared<const rcand::r2r_wire::Ed25519Key>(rcand::r2r_wire::Ed25519Key::generate());
  fleet.add("alex", {"nav"}, FleetPose{}, hardening_signed_settings(alex_key, "bob", bob_key));
  Robot& bob = fleet.add("bob", {"teleop"}, FleetPose{}, hardening_signed_settings(bob_key, "alex", alex_key));
  fleet.advance(10ms);
  // alex's last will, signed when it connected an hour ago (long before bob started).
  const auto signed_status = [&](const std::string& state, double age_s) {
    json message{{"header", {{"version", "1.0"}, {"timestamp", fleet.clock.wall_ms() / 1000.0 - age_s}, {"source_id", "alex"}}},
                 {"type", "status"},
                 {"payload", {{"state", state}, {"estopped", false}, {"battery", nullptr}, {"position", nullptr}}}};
    rcand::r2r_wire::sign_message(message, "alex", *alex_key);
    return message.dump();
  };
  const auto deliver = [&](const std::string& bytes, const std::string& topic) {
    InboundMessage message;
    message.bytes = bytes;
    message.transport = "mqtt";
    message.peer = topic;
    message.broadcast = true;
    message.status_topic = topic.starts_with("r2r/status/");
    bob.node->receive(std::move(message));
  };
  const auto alex_state = [&]() -> std::string {
    const json doc = bob.node->peers();
    for (const auto& peer : doc["peers"])
      if (peer["name"] == "alex" && peer["status"].is_object()) return peer["status"].value("state", "");
    return "";
  };
  const auto rejected = [&] { return bob.node->counters().rejected; };

  // Not on alex's own status topic: the stale signature is refused, whatever it says.
  REQUIRE(alex_state() == "idle");  // alex's live status, heard over the in-memory network
  auto before = rejected();
  deliver(signed_status("offline", 3600), "r2r/broadcast");
  deliver(signed_status("offline", 3600), "r2r/status/carol");
  CHECK(rejected() == before + 2);
  CHECK(alex_state() == "idle");
  // A live status an hour old is stale on any topic.
  deliver(signed_status("running", 3600), "r2r/status/alex");
  CHECK(rejected() == before + 3);
  CHECK(alex_state() == "idle");
  // The will on alex's own topic: verified as of its own timestamp, and alex shows offline.
  deliver(signed_status("offline", 3600), "r2r/status/alex");
  CHECK(alex_state() == "offline");
  // A retained live status set just before bob started (inside the window) is taken from alex's topic.
  deliver(signed_status("running", 1), "r2r/status/alex");
  CHECK(alex_state() == "running");
}
