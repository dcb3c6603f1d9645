// Issue 31 (fleet e-stop over MQTT, docs/protocol.md §11.13) against a real mosquitto and three real rcand robots:
// `rcanctl fleet stop --mqtt` (a signed R2R command {"type":"estop"} on r2r/broadcast) latches all three, each naming
// the sender and its reason, audited with the sender as principal, and each robot publishes its latched status; an
// unsigned stop and one signed by a key no robot has enrolled latch none and are never answered on the wire.
#include <doctest/doctest.h>

#include <chrono>
#include <mutex>

#include "mosquitto_broker.hpp"
#include "r2r_lab.hpp"
#include "rcand_process.hpp"
#include "services/r2r/message_auth.hpp"
#include "services/r2r/transports/mqtt_transport.hpp"

using namespace rcand::test;
using nlohmann::json;
using namespace std::chrono_literals;
using rcand::kernel::r2r::Ed25519Key;

namespace {

// Everything on the broker's r2r/#, as the test's own MQTT client sees it.
struct FleetWire {
  rcand::kernel::r2r::MqttTransport client;
  std::mutex mutex;
  std::vector<json> messages;

  explicit FleetWire(std::uint16_t port)
      : client([&] {
          rcand::kernel::r2r::MqttOptions options;
          options.robot_name = "fleet-wire";
          options.host = "127.0.0.1";
          options.port = port;
          options.extra_subscriptions = {"r2r/#"};
          return options;
        }()) {
    client.start([this](rcand::kernel::r2r::InboundMessage message) {
      const json m = json::parse(message.bytes, nullptr, false);
      if (!m.is_object() || !m.contains("header") || !m["header"].is_object()) return;
      std::lock_guard lock(mutex);
      messages.push_back(m);
    });
    REQUIRE(poll_until<bool>([&]() -> std::optional<bool> {
      if (client.connected()) return true;
      return std::nullopt;
    }));
  }
  ~FleetWire() { client.stop(); }

  // Messages of `type` from `source` satisfying `match`.
  std::size_t count(
      const std::string& type, const std::string& source,
      const std::function<bool(const json&)>& match = [](const json&) { return true; }) {
    std::lock_guard lock(mutex);
    std::size_t n = 0;
    for (const auto& m : messages) n += m.value("type", "") == type && m["header"].value("source_id", "") == source && match(m);
    return n;
  }
  std::size_t errors() {
    std::lock_guard lock(mutex);
    std::size_t n = 0;
    for (const auto& m : messages) n += m.value("type", "") == "error";
    return n;
  }
};

const std::vector<std::string> kFleetNames{"alpha", "bravo", "charlie"};

json fleet_robot(const std::string& name, const std::filesystem::path& token, std::uint16_t broker, const json& peers) {
  auto config = r2r_robot_config(name, token);
  config["runtime"]["r2r"]["mqtt"] = {{"host", "127.0.0.1"}, {"port", broker}, {"keepalive_s", 5}};
  config["runtime"]["r2r"]["status_interval_ms"] = 60000;  // a latched status seen soon was sent at once
  config["runtime"]["r2r"]["peers"] = peers;
  return config;
}

bool fleet_latched(const RcandProcess& robot) { return robot.json("GET", "/api/status", "guest-token").value("estopped", false); }

}  // namespace

TEST_CASE("fleet e-stop (mqtt): rcanctl fleet stop latches three robots; unsigned and unenrolled stops latch none, unanswered") {
  MosquittoBroker broker;
  TempDir dir;
  const auto token = dir.write("r2r.token", "owner-token\n");
  const Ed25519Key ops = Ed25519Key::generate();
  const auto ops_key = dir.write("ops.pem", ops.private_pem());
  std::filesystem::permissions(ops_key, std::filesystem::perms::owner_read | std::filesystem::perms::owner_write);
  const Ed25519Key stranger = Ed25519Key::generate();
  // GUEST: a stop needs scope status only, as POST /api/stop.
  const json peers = json::array({{{"name", "ops"}, {"public_key", ops.public_base64()}, {"role", "GUEST"}}});
  FleetWire wire(broker.port());
  std::vector<std::unique_ptr<RcandProcess>> robots;
  for (const auto& name : kFleetNames)
    robots.push_back(std::make_unique<RcandProcess>(fleet_robot(name, token, broker.port(), peers)));
  REQUIRE(poll_until<bool>(
      [&]() -> std::optional<bool> {
        for (const auto& name : kFleetNames)
          if (wire.count("status", name) == 0) return std::nullopt;
        return true;
      },
      30s));

  // An unsigned stop, and one signed by a key no robot enrolled: both broadcasts, both refused by every robot.
  auto rejected = [](const RcandProcess& robot) {
    return robot.json("GET", "/api/r2r/peers", "owner-token")["counters"]["rejected"].get<int>();
  };
  REQUIRE(wire.client.send(r2r_message("ops", "command", {{"type", "estop"}, {"reason", "unsigned"}}), std::nullopt));
  json forged = json::parse(r2r_message("stranger", "command", {{"type", "estop"}, {"reason", "unenrolled"}}));
  rcand::kernel::r2r::sign_message(forged, "stranger", stranger);
  REQUIRE(wire.client.send(forged.dump(), std::nullopt));
  for (const auto& robot : robots) {
    REQUIRE(poll_until<bool>([&]() -> std::optional<bool> {
      if (rejected(*robot) >= 2) return true;
      return std::nullopt;
    }));
    CHECK_FALSE(fleet_latched(*robot));
    const std::string log = robot->stderr_text();
    CHECK(log.find("unauthorized fleet e-stop from 'ops' via mqtt") != std::string::npos);
    CHECK(log.find("unauthorized fleet e-stop from 'stranger' via mqtt: unknown signing key 'stranger'") != std::string::npos);
  }
  CHECK(wire.errors() == 0);  // a broadcast is never answered

  // The operator's stop: signed with the enrolled key, acknowledged by the broker.
  const auto result =
      run_tool(rcanctl_binary(), {"fleet", "stop", "--mqtt", "127.0.0.1:" + std::to_string(broker.port()), "--key",
                                  ops_key.string(), "--name", "ops", "--reason", "aisle 3 blocked", "--json"});
  INFO("rcanctl: " << result.out << result.err);
  REQUIRE(result.exit_code == 0);
  const json printed = json::parse(result.out, nullptr, false);
  CHECK(printed.value("published", false));
  CHECK(printed.value("topic", "") == "r2r/broadcast");
  for (std::size_t i = 0; i < robots.size(); ++i) {
    const RcandProcess& robot = *robots[i];
    REQUIRE(poll_until<bool>([&]() -> std::optional<bool> {
      if (fleet_latched(robot)) return true;
      return std::nullopt;
    }));
    const json estop = robot.json("GET", "/api/estop", "guest-token");
    CHECK(estop["reason"] == "fleet e-stop from 'ops': aisle 3 blocked");
    CHECK(estop["principal"] == "ops");
    CHECK(estop["from"] == "r2r ops");
    // Audited as the sender, as POST /api/stop.
    const json audit = robot.json("GET", "/api/audit?limit=20", "owner-token");
    bool audited = false;
    for (const auto& entry : audit["entries"])
      audited = audited || (entry.value("principal", "") == "ops" && entry.value("event", "") == "POST /api/stop");
    CHECK(audited);
    // The latched status on the wire, long before the 60 s interval.
    const std::string& name = kFleetNames[i];
    CHECK(poll_until<bool>([&]() -> std::optional<bool> {
      if (wire.count("status", name, [](const json& m) { return m["payload"].value("estopped", false); }) > 0) return true;
      return std::nullopt;
    }));
  }
  CHECK(wire.errors() == 0);
}
