// docs/protocol.md §11.3 (issue 20): a WebSocket client's message for another robot of the fleet is relayed once by
// the robot it is connected to - to a robot named in swarm.yaml or one heard from as an R2R peer - over WebSocket or
// MQTT, with the hop marker header.relayed_by. The target checks the sender's own credentials (a signature still
// verifies; a tampered copy does not), its answer comes back through the relay, a marked message is never relayed
// again, and only a target no transport knows is 101.
#include <doctest/doctest.h>
#include <signal.h>

#include <chrono>
#include <mutex>

#include "libs/r2r_wire/message_signature.hpp"
#include "mosquitto_broker.hpp"
#include "r2r_lab.hpp"
#include "rcand_process.hpp"
#include "services/r2r/transports/mqtt_transport.hpp"
#include "temp_dir.hpp"
#include "ws_client.hpp"

using namespace rcand::test;
using nlohmann::json;
using namespace std::chrono_literals;
using rcand::r2r_wire::Ed25519Key;

namespace {

const json kRelayedMove = {{"type", "move"}, {"linear", 0.3}, {"angular", 0.0}, {"duration_ms", 3000}};

// A command from `source` for `target`, carrying the fleet token (what the target checks).
std::string relay_command(const std::string& source, const std::string& target) {
  json message = json::parse(r2r_message(source, "command", kRelayedMove, target));
  message["header"]["auth"] = {{"token", "owner-token"}};
  return message.dump();
}

std::optional<bool> relay_moving(const RcandProcess& robot) {
  if (drive_status(robot)["moving"] == true) return true;
  return std::nullopt;
}

// Each robot signs with a key of its own and accepts the others' and the client's (role USER): MQTT carries no token.
struct RelayKeys {
  rcand::r2r_wire::Ed25519Key client = rcand::r2r_wire::Ed25519Key::generate();
  void sign_robots(const std::vector<json*>& configs, const TempDir& dir) const {
    std::vector<std::pair<std::string, std::filesystem::path>> public_keys{
        {"client", dir.write("client.pub.pem", client.public_pem())}};
    for (json* config : configs) {
      const std::string name = (*config)["metadata"]["robot_name"];
      const auto key = rcand::r2r_wire::Ed25519Key::generate();
      (*config)["runtime"]["r2r"]["private_key_file"] = dir.write(name + ".pem", key.private_pem()).string();
      public_keys.emplace_back(name, dir.write(name + ".pub.pem", key.public_pem()));
    }
    for (json* config : configs) {
      json peers = json::array();
      for (const auto& [name, file] : public_keys)
        if (name != (*config)["metadata"]["robot_name"])
          peers.push_back({{"name", name}, {"public_key_file", file.string()}, {"role", "USER"}});
      (*config)["runtime"]["r2r"]["peers"] = std::move(peers);
    }
  }
  // A command signed by the client (no token).
  json signed_command(const std::string& target) const {
    json message = json::parse(r2r_message("client", "command", kRelayedMove, target));
    rcand::r2r_wire::sign_message(message, "client", client);
    return message;
  }
};

}  // namespace

TEST_CASE("r2r relay (ws): to a swarm.yaml robot and to a robot heard from; answers come back; marked or unknown is 101") {
  TempDir dir;
  const auto token = dir.write("r2r.token", "owner-token\n");
  RcandProcess bravo(r2r_robot_config("bravo", token));
  RcandProcess alpha(
      r2r_robot_config("alpha", token, 0, 0, dir.write("alpha-swarm.yaml", swarm_yaml({{"bravo", "127.0.0.1", bravo.port()}}))));
  // charlie is not in alpha's swarm.yaml; alpha is in charlie's, so charlie dials it and alpha hears its status.
  RcandProcess charlie(r2r_robot_config("charlie", token, 0, 0,
                                        dir.write("charlie-swarm.yaml", swarm_yaml({{"alpha", "127.0.0.1", alpha.port()}}))));
  REQUIRE(poll_until<json>([&] { return peer_status(alpha, "charlie"); }));

  WsClient client;
  REQUIRE(client.connect(alpha.port(), "user-token") == 101);

  client.send(relay_command("client", "bravo"));  // named in alpha's swarm.yaml: dialed and relayed
  CHECK(poll_until<bool>([&] { return relay_moving(bravo); }));
  client.send(relay_command("client", "charlie"));  // heard from: relayed on charlie's own connection
  CHECK(poll_until<bool>([&] { return relay_moving(charlie); }));
  CHECK(drive_status(alpha)["moving"] == false);
  CHECK(alpha.json("GET", "/api/r2r/peers", "guest-token")["counters"]["relayed"] == 2);

  // bravo's answer (105: its e-stop is latched) is addressed to the client and comes back through alpha.
  bravo.json("POST", "/api/stop", "guest-token");
  client.send(relay_command("client", "bravo"));
  const auto refused = read_until(client, error_with(105));
  REQUIRE(refused);
  CHECK((*refused)["header"]["source_id"] == "bravo");
  CHECK((*refused)["header"]["target_id"] == "client");
  CHECK((*refused)["header"]["relayed_by"] == "alpha");
  CHECK(drive_status(bravo)["moving"] == false);

  // A relayed message is never relayed again (no loop, whoever knows whom); a target nobody knows is 101.
  charlie.json("POST", "/api/stop", "guest-token");  // halts the earlier move; cleared, charlie stays still
  charlie.json("POST", "/api/estop/clear", "owner-token");
  json marked = json::parse(relay_command("client", "charlie"));
  marked["header"]["relayed_by"] = "bravo";
  client.send(marked.dump());
  auto answer = read_until(client, error_with(101));
  REQUIRE(answer);
  CHECK(answer->at("payload")["message"].get<std::string>().find("never relayed again") != std::string::npos);
  client.send(relay_command("client", "nobody"));
  answer = read_until(client, error_with(101));
  REQUIRE(answer);
  CHECK(answer->at("payload")["message"].get<std::string>().find("unknown target robot 'nobody'") != std::string::npos);
  // Relayed: two commands, the third to bravo and bravo's answer to it; neither of the refused ones.
  CHECK(alpha.json("GET", "/api/r2r/peers", "guest-token")["counters"]["relayed"] == 4);
  CHECK(drive_status(charlie)["moving"] == false);
}

TEST_CASE("r2r relay (ws): a robot that a SIGHUP reload adds to swarm.yaml is dialed and relayed to") {
  TempDir dir;
  const auto token = dir.write("r2r.token", "owner-token\n");
  RcandProcess bravo(r2r_robot_config("bravo", token));
  const auto swarm_file = dir.path() / "swarm.yaml";  // none yet: alpha starts knowing no robot
  RcandProcess alpha(r2r_robot_config("alpha", token, 0, 0, swarm_file));
  WsClient client;
  REQUIRE(client.connect(alpha.port(), "user-token") == 101);
  client.send(relay_command("client", "bravo"));
  REQUIRE(read_until(client, error_with(101)));

  dir.write("swarm.yaml", swarm_yaml({{"bravo", "127.0.0.1", bravo.port()}}));
  REQUIRE(::kill(alpha.pid(), SIGHUP) == 0);
  REQUIRE(poll_until<bool>([&]() -> std::optional<bool> {
    if (alpha.stderr_text().find("config reload from") != std::string::npos) return true;
    return std::nullopt;
  }));
  client.send(relay_command("client", "bravo"));  // now a robot of the fleet: dialed with the new file's token
  CHECK(poll_until<bool>([&] { return relay_moving(bravo); }));
  CHECK(alpha.json("GET", "/api/r2r/peers", "guest-token")["counters"]["relayed"] == 1);
}

TEST_CASE("r2r relay (ws): a signed message verifies at the target as its sender; a tampered relayed copy is refused") {
  TempDir dir;
  const auto token = dir.write("r2r.token", "owner-token\n");
  RelayKeys keys;
  auto bravo_config = r2r_robot_config("bravo", token);
  auto alpha_config = r2r_robot_config("alpha", token);
  keys.sign_robots({&bravo_config, &alpha_config}, dir);
  RcandProcess bravo(bravo_config);
  alpha_config["runtime"]["swarm_file"] = dir.write("swarm.yaml", swarm_yaml({{"bravo", "127.0.0.1", bravo.port()}})).string();
  RcandProcess alpha(alpha_config);

  WsClient client;
  REQUIRE(client.connect(alpha.port(), "user-token") == 101);
  const json message = keys.signed_command("bravo");
  client.send(message.dump());
  CHECK(poll_until<bool>([&] { return relay_moving(bravo); }));
  const auto audit = bravo.json("GET", "/api/audit?limit=50", "owner-token");
  bool by_client = false;
  for (const auto& entry : audit["entries"]) by_client = by_client || entry.value("principal", "") == "client";
  CHECK(by_client);  // the target ran it as the signer, not as alpha

  // The relayed copy with its payload changed on the way: the signature no longer holds at bravo (103).
  json tampered = message;
  tampered["header"]["relayed_by"] = "alpha";
  tampered["payload"]["linear"] = 1.0;
  WsClient path;
  REQUIRE(path.connect(bravo.port(), "user-token") == 101);
  path.send(tampered.dump());
  const auto refused = read_until(path, error_with(103));
  REQUIRE(refused);
  CHECK(refused->at("payload")["message"].get<std::string>().find("bad signature") != std::string::npos);
  // The untouched copy sent again is a replay: dropped, whichever way it comes.
  const auto rejected = bravo.json("GET", "/api/r2r/peers", "guest-token")["counters"]["rejected"].get<int>();
  path.send(message.dump());
  CHECK(poll_until<bool>([&]() -> std::optional<bool> {
    if (bravo.json("GET", "/api/r2r/peers", "guest-token")["counters"]["rejected"].get<int>() > rejected) return true;
    return std::nullopt;
  }));
}

TEST_CASE("r2r relay (mqtt): a WebSocket client's signed command reaches a robot heard on the broker; the answer returns") {
  MosquittoBroker broker;
  TempDir dir;
  const auto token = dir.write("r2r.token", "owner-token\n");
  RelayKeys keys;
  auto with_mqtt = [&](json config) {
    // Each learns of the other from its status (r2r/status/<name>): alpha relays to bravo, bravo answers through alpha.
    config["runtime"]["r2r"]["mqtt"] = {
        {"host", "127.0.0.1"}, {"port", broker.port()}, {"keepalive_s", 5}, {"status_subscriptions", "all"}};
    return config;
  };
  auto bravo_config = with_mqtt(r2r_robot_config("bravo", token));
  auto alpha_config = with_mqtt(r2r_robot_config("alpha", token));
  keys.sign_robots({&bravo_config, &alpha_config}, dir);
  RcandProcess bravo(bravo_config);
  RcandProcess alpha(alpha_config);
  REQUIRE(poll_until<json>([&] { return peer_status(alpha, "bravo"); }));  // heard on r2r/status/bravo

  rcand::services::r2r::MqttOptions observer_options;
  observer_options.robot_name = "relay-observer";
  observer_options.host = "127.0.0.1";
  observer_options.port = broker.port();
  observer_options.extra_subscriptions = {"r2r/bravo"};
  rcand::services::r2r::MqttTransport observer(observer_options);
  std::mutex seen_mutex;
  std::vector<json> seen;
  observer.start([&](rcand::services::r2r::InboundMessage m) {
    std::lock_guard lock(seen_mutex);
    seen.push_back(json::parse(m.bytes, nullptr, false));
  });
  REQUIRE(poll_until<bool>([&]() -> std::optional<bool> {
    if (observer.connected()) return true;
    return std::nullopt;
  }));

  WsClient client;
  REQUIRE(client.connect(alpha.port(), "user-token") == 101);
  const json message = keys.signed_command("bravo");
  client.send(message.dump());
  CHECK(poll_until<bool>([&] { return relay_moving(bravo); }));
  const auto relayed = poll_until<json>([&]() -> std::optional<json> {
    std::lock_guard lock(seen_mutex);
    for (const auto& m : seen)
      if (m.is_object() && m["header"].value("relayed_by", "") == "alpha") return m;
    return std::nullopt;
  });
  REQUIRE(relayed);
  CHECK((*relayed)["header"]["source_id"] == "client");
  CHECK((*relayed)["header"]["signature"] == message["header"]["signature"]);  // the client's, untouched
  CHECK_FALSE((*relayed)["header"].contains("auth"));

  // A tampered copy published on bravo's topic: refused (103), and the answer finds the client through alpha.
  json tampered = *relayed;
  tampered["payload"]["linear"] = 1.0;
  REQUIRE(observer.send(tampered.dump(), std::string("bravo")));
  auto answer = read_until(client, error_with(103));
  REQUIRE(answer);
  CHECK((*answer)["header"]["source_id"] == "bravo");

  // bravo's 105 (e-stop latched) comes back over MQTT to alpha, which passes it on to the client.
  bravo.json("POST", "/api/stop", "guest-token");
  client.send(keys.signed_command("bravo").dump());
  answer = read_until(client, error_with(105));
  REQUIRE(answer);
  CHECK((*answer)["header"]["target_id"] == "client");
  CHECK(drive_status(bravo)["moving"] == false);
  observer.stop();
}
