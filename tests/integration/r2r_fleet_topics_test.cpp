// The fleet's MQTT topic layout against real rcand robots and a real mosquitto the tests start (docs/protocol.md §11.2,
// issue 31): status on r2r/status/<name> (retained, last will `offline`, read only by who subscribes), the broker ACL
// of docs/examples/mosquitto-acl.conf, and a robot that loses its broker keeping its local safety and rejoining.
#include <doctest/doctest.h>

#include <cstdio>

#include "eventually.hpp"
#include "libs/r2r_wire/message_signature.hpp"
#include "mosquitto_broker.hpp"
#include "mqtt_watch.hpp"
#include "r2r_lab.hpp"
#include "rcand_process.hpp"

using namespace rcand::test;
using nlohmann::json;
using namespace std::chrono_literals;

namespace {

bool topics_status_from(const json& m, const std::string& robot) {
  return wire_field(m, "/type") == "status" && wire_field(m, "/header/source_id") == robot;
}

// The retained message on `topic`, read by mosquitto_sub as a fresh client would (empty when there is none).
std::string topics_retained_on(std::uint16_t port, const std::string& topic) {
  const std::string command =
      "mosquitto_sub -h 127.0.0.1 -p " + std::to_string(port) + " -t '" + topic + "' -C 1 -W 5 --retained-only 2>/dev/null";
  std::string out;
  if (FILE* pipe = ::popen(command.c_str(), "r")) {
    char buffer[4096];
    while (const std::size_t n = std::fread(buffer, 1, sizeof buffer, pipe)) out.append(buffer, n);
    ::pclose(pipe);
  }
  return out;
}

std::optional<json> topics_peer_state(const RcandProcess& robot, const std::string& name, const std::string& state) {
  const auto peer = peer_status(robot, name);
  if (peer && (*peer)["status"].value("state", "") == state) return peer;
  return std::nullopt;
}

json topics_with_broker(json config, std::uint16_t port, json extra = json::object()) {
  json mqtt = {{"host", "127.0.0.1"}, {"port", port}, {"keepalive_s", 5}};
  mqtt.update(extra);
  config["runtime"]["r2r"]["mqtt"] = std::move(mqtt);
  return config;
}

}  // namespace

TEST_CASE("r2r topics (mqtt): status on r2r/status/<name>, retained, read only by subscribers; offline on crash and stop") {
  MosquittoBroker broker;
  TempDir dir;
  const auto token = dir.write("r2r.token", "owner-token\n");
  auto alpha_config = topics_with_broker(r2r_robot_config("alpha", token), broker.port(), {{"status_subscriptions", "all"}});
  auto bravo_config = topics_with_broker(r2r_robot_config("bravo", token), broker.port());  // reads no one's status
  auto charlie_config = topics_with_broker(r2r_robot_config("charlie", token), broker.port());
  sign_fleet({&alpha_config, &bravo_config, &charlie_config}, dir);
  auto watch_options = mqtt_client("watch", broker.port());
  watch_options.extra_subscriptions = {"r2r/#"};
  MqttWatch watch(watch_options);
  RcandProcess alpha(alpha_config);
  RcandProcess bravo(bravo_config);
  RcandProcess charlie(charlie_config);

  // alpha (status_subscriptions: all) reads both; each status is on its sender's own topic, none on r2r/broadcast.
  REQUIRE(poll_until<json>([&] { return peer_status(alpha, "bravo"); }));
  REQUIRE(poll_until<json>([&] { return peer_status(alpha, "charlie"); }));
  REQUIRE(poll_until<bool>([&]() -> std::optional<bool> {
    if (watch.count([](const std::string&, const json& m) { return topics_status_from(m, "alpha"); }) >= 3) return true;
    return std::nullopt;
  }));
  CHECK(watch.count([](const std::string& topic, const json& m) {
    return wire_field(m, "/type") == "status" && topic == "r2r/broadcast";
  }) == 0);
  CHECK(watch.count([](const std::string& topic, const json& m) {
    return wire_field(m, "/type") == "status" && topic != "r2r/status/" + wire_field(m, "/header/source_id");
  }) == 0);
  // bravo subscribed to no status: alpha's three statuses reached the broker, bravo received nothing at all.
  CHECK(bravo.json("GET", "/api/r2r/peers", "owner-token")["counters"]["received"] == 0);
  CHECK_FALSE(peer_status(bravo, "alpha"));

  // Retained: a client that subscribes now gets bravo's latest status at once.
  const json retained = json::parse(topics_retained_on(broker.port(), "r2r/status/bravo"), nullptr, false);
  REQUIRE(retained.is_object());
  CHECK(topics_status_from(retained, "bravo"));
  CHECK(retained["payload"]["state"] == "idle");

  // bravo dies (SIGKILL: no clean shutdown): the broker publishes its last will, a signed `offline` status, which
  // alpha verifies and shows.
  bravo.kill_hard();
  const auto will = watch.wait_for([](const std::string& topic, const json& m) {
    return topic == "r2r/status/bravo" && topics_status_from(m, "bravo") && wire_field(m, "/payload/state") == "offline";
  });
  REQUIRE(will);
  CHECK(will->second["header"].contains("signature"));
  CHECK(poll_until<json>([&] { return topics_peer_state(alpha, "bravo", "offline"); }));
  const json left = json::parse(topics_retained_on(broker.port(), "r2r/status/bravo"), nullptr, false);
  CHECK(left.is_object());
  CHECK(left["payload"]["state"] == "offline");

  // charlie stops cleanly (SIGTERM: a clean DISCONNECT discards the will): it leaves `offline` there itself.
  CHECK(charlie.stop() == 0);
  CHECK(poll_until<json>([&] { return topics_peer_state(alpha, "charlie", "offline"); }));
  const json stopped = json::parse(topics_retained_on(broker.port(), "r2r/status/charlie"), nullptr, false);
  REQUIRE(stopped.is_object());
  CHECK(topics_status_from(stopped, "charlie"));
  CHECK(stopped["payload"]["state"] == "offline");
}

TEST_CASE("r2r topics (mqtt): the example broker ACL keeps each robot to its own status and direct topic") {
  TempDir dir;
  const std::vector<BrokerUser> users = {
      {"alpha", "pw-alpha"}, {"bravo", "pw-bravo"}, {"charlie", "pw-charlie"}, {"delta", "pw-delta"}};
  MosquittoBroker broker(users, std::filesystem::path(RCAND_SOURCE_DIR) / "docs/examples/mosquitto-acl.conf");
  const auto token = dir.write("r2r.token", "owner-token\n");
  auto robot = [&](const std::string& name, json extra) {
    extra["username"] = name;
    extra["password_file"] = dir.write(name + ".mqtt-password", "pw-" + name + "\n").string();
    return topics_with_broker(r2r_robot_config(name, token), broker.port(), extra);
  };
  auto alpha_config = robot("alpha", {{"status_subscriptions", "all"}});
  auto bravo_config = robot("bravo", json::object());
  sign_fleet({&alpha_config, &bravo_config}, dir);
  RcandProcess alpha(alpha_config);
  RcandProcess bravo(bravo_config);

  // The fleet works under the ACL: bravo's status reaches alpha, alpha's command moves bravo.
  REQUIRE(poll_until<json>([&] { return peer_status(alpha, "bravo"); }));
  int status = 0;
  const int commands_before = drive_status(bravo)["commands"].get<int>();
  const json sent = alpha.json("POST", "/api/r2r/send", "user-token",
                               json{{"type", "command"},
                                    {"target", "bravo"},
                                    {"payload", {{"type", "move"}, {"linear", 0.3}, {"angular", 0.0}, {"duration_ms", 3000}}}}
                                   .dump(),
                               &status);
  REQUIRE(status == 200);
  const auto moved = poll_until<bool>([&]() -> std::optional<bool> {
    if (drive_status(bravo)["moving"] == true || drive_status(bravo)["commands"].get<int>() > commands_before) return true;
    return std::nullopt;
  });
  INFO("sent: " << sent.dump() << "\nbravo's log:\n" << bravo.stderr_text() << "\nalpha's log:\n" << alpha.stderr_text());
  REQUIRE(moved);

  // delta, a third robot reading every status (and the broadcasts), is the witness.
  auto witness_options = mqtt_client("delta", broker.port());
  witness_options.username = "delta";
  witness_options.password_file = dir.write("delta.mqtt-password", "pw-delta\n");
  witness_options.status_of_all = true;
  MqttWatch witness(witness_options);
  // charlie, logged in as itself, poses as bravo: its status goes to r2r/status/bravo, its own topic is r2r/bravo, its
  // client id is bravo's (rcand-bravo; use_username_as_clientid keeps it from taking over bravo's session).
  auto intruder_options = mqtt_client("bravo", broker.port());
  intruder_options.username = "charlie";
  intruder_options.password_file = dir.write("charlie.mqtt-password", "pw-charlie\n");
  intruder_options.extra_subscriptions = {"r2r/charlie"};  // its own direct topic: allowed
  MqttWatch intruder(intruder_options);
  REQUIRE(eventually([&] { return witness.transport().connected() && intruder.transport().connected(); }));
  REQUIRE(witness.wait_for([](const std::string&, const json& m) { return topics_status_from(m, "bravo"); }));

  // The forged status is dropped by the broker: the witness gets the intruder's next broadcast, never the forgery.
  const std::string forged = r2r_message("bravo", "status", {{"state", "forged"}, {"estopped", true}});
  const std::string sentinel = r2r_message("charlie", "task_request", {{"task_id", "acl-sentinel"}, {"description", "x"}});
  REQUIRE(eventually([&] {
    intruder.transport().send(forged, std::nullopt);
    intruder.transport().send(sentinel, std::nullopt);
    return witness.count([](const std::string& topic, const json& m) {
      return topic == "r2r/broadcast" && wire_field(m, "/payload/task_id") == "acl-sentinel";
    }) > 0;
  }));
  CHECK(witness.count([](const std::string&, const json& m) { return wire_field(m, "/payload/state") == "forged"; }) == 0);
  CHECK_FALSE(topics_peer_state(alpha, "bravo", "forged"));

  // Reading bravo's direct topic is refused: alpha's next command for bravo reaches bravo (its log of commands grows)
  // and not the intruder, which still gets what is sent to r2r/charlie afterwards.
  const int commands = drive_status(bravo)["commands"].get<int>();
  alpha.json("POST", "/api/r2r/send", "user-token",
             json{{"type", "command"},
                  {"target", "bravo"},
                  {"payload", {{"type", "move"}, {"linear", 0.1}, {"angular", 0.0}, {"duration_ms", 200}}}}
                 .dump(),
             &status);
  REQUIRE(status == 200);
  REQUIRE(poll_until<bool>([&]() -> std::optional<bool> {
    if (drive_status(bravo)["commands"].get<int>() > commands) return true;
    return std::nullopt;
  }));
  REQUIRE(witness.transport().send(r2r_message("delta", "negotiation", {{"task_id", "acl-direct"}, {"action", "withdraw"}}),
                                   std::string("charlie")));
  REQUIRE(intruder.wait_for([](const std::string& topic, const json& m) {
    return topic == "r2r/charlie" && wire_field(m, "/payload/task_id") == "acl-direct";
  }));
  CHECK(intruder.count([](const std::string& topic, const json&) { return topic == "r2r/bravo"; }) == 0);
}

TEST_CASE("r2r topics (mqtt): a robot that loses its broker keeps its local safety and rejoins when it is back") {
  MosquittoBroker broker;
  TempDir dir;
  const auto token = dir.write("r2r.token", "owner-token\n");
  auto alpha_config = topics_with_broker(r2r_robot_config("alpha", token), broker.port());
  sign_fleet({&alpha_config}, dir);
  RcandProcess alpha(alpha_config);
  const auto link_up = [&]() -> std::optional<bool> {
    return alpha.json("GET", "/api/r2r/peers", "owner-token")["transports"]["mqtt"]["connected"].get<bool>();
  };
  const auto link_is = [&](bool up) {
    return poll_until<bool>(
        [&]() -> std::optional<bool> {
          if (link_up() == up) return true;
          return std::nullopt;
        },
        40s);
  };
  REQUIRE(link_is(true));
  int status = 0;
  alpha.json("POST", "/api/action", "user-token", R"({"type":"move","linear":0.5,"angular":0.1,"duration_ms":8000})", &status);
  REQUIRE(status == 200);
  REQUIRE(drive_status(alpha)["moving"] == true);

  // The broker dies (SIGKILL, by PID) while alpha moves: alpha sees its R2R link down.
  broker.kill_hard();
  REQUIRE(link_is(false));
  CHECK(drive_status(alpha)["moving"] == true);  // the R2R link is no motion source: the move goes on

  // Local safety needs no broker: the stop latches and halts within the 500 ms MUST; teleop is refused while latched.
  const auto before = std::chrono::steady_clock::now();
  const auto stopped = alpha.json("POST", "/api/stop", "guest-token", "", &status);
  const auto elapsed = std::chrono::steady_clock::now() - before;
  REQUIRE(status == 200);
  CHECK(elapsed < 500ms);
  CHECK(stopped["estopped"] == true);
  CHECK(drive_status(alpha)["moving"] == false);
  alpha.json("POST", "/api/action", "user-token", R"({"type":"move","linear":0.2,"angular":0})", &status);
  CHECK(status == 423);
  CHECK(drive_status(alpha)["moving"] == false);
  CHECK(alpha.json("GET", "/health")["status"] == "ok");

  // The broker comes back on the same port: alpha reconnects by itself and its retained status (latched) is there.
  broker.start();
  REQUIRE(link_is(true));
  const auto back = poll_until<json>(
      [&]() -> std::optional<json> {
        const json retained = json::parse(topics_retained_on(broker.port(), "r2r/status/alpha"), nullptr, false);
        if (retained.is_object() && retained["payload"]["estopped"] == true) return retained;
        return std::nullopt;
      },
      20s);
  REQUIRE(back);
  CHECK((*back)["payload"]["state"] == "estop");
}
