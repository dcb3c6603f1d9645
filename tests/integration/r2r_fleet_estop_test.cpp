// Issue 31 (fleet e-stop over MQTT, docs/protocol.md §11.13) against a real mosquitto and three real rcand robots:
// `rcanctl fleet stop --mqtt` (a signed R2R command {"type":"estop"} on r2r/broadcast) latches all three, each naming
// the sender and its reason, audited with the sender as principal, and each robot publishes its latched status; an
// unsigned stop and one signed by a key no robot has enrolled latch none and are never answered on the wire.
// `rcanctl r2r watch --mqtt` shows an operator the broker's traffic.
#include <doctest/doctest.h>

#include <signal.h>

#include <chrono>
#include <set>
#include <sstream>

#include "libs/r2r_wire/message_signature.hpp"
#include "mosquitto_broker.hpp"
#include "mqtt_watch.hpp"
#include "r2r_lab.hpp"
#include "rcand_process.hpp"

using namespace rcand::test;
using nlohmann::json;
using namespace std::chrono_literals;
using rcand::r2r_wire::Ed25519Key;

namespace {

const std::vector<std::string> kFleetNames{"alpha", "bravo", "charlie"};

json fleet_robot(const std::string& name, const std::filesystem::path& token, std::uint16_t broker,
                 const std::filesystem::path& peers_file) {
  auto config = r2r_robot_config(name, token);
  config["runtime"]["r2r"]["mqtt"] = {{"host", "127.0.0.1"}, {"port", broker}, {"keepalive_s", 5}};
  config["runtime"]["r2r"]["status_interval_ms"] = 60000;  // a latched status seen soon was sent at once
  config["runtime"]["r2r"]["peers_file"] = peers_file.string();
  return config;
}

ProcessResult fleet_tool(const std::vector<std::string>& args) {
  std::vector<std::string> words{"fleet"};
  words.insert(words.end(), args.begin(), args.end());
  return run_tool(rcanctl_binary(), words);
}

bool fleet_latched(const RcandProcess& robot) { return robot.json("GET", "/api/status", "guest-token").value("estopped", false); }

}  // namespace

TEST_CASE(
    "fleet e-stop (mqtt): unsigned and unenrolled stops latch none, unanswered; enroll + SIGHUP admits a sender; "
    "rcanctl fleet stop latches three robots") {
  MosquittoBroker broker;
  TempDir dir;
  const auto token = dir.write("r2r.token", "owner-token\n");
  const std::string keys = (dir.path() / "keys").string();
  const std::string peers_file = (dir.path() / "fleet-peers.yaml").string();
  // The operator's keys, made and enrolled as the README says; "ops" as GUEST: a stop needs scope status only.
  for (const std::string name : {"ops", "stranger"}) REQUIRE(fleet_tool({"keygen", name, "--out", keys}).exit_code == 0);
  REQUIRE(fleet_tool({"enroll", "--peers-file", peers_file, "ops", keys + "/ops.pub", "--role", "guest"}).exit_code == 0);
  MqttWatch wire(mqtt_client("fleet-wire", broker.port(), {"r2r/#"}));  // everything on the broker's r2r/#
  REQUIRE(wire.connected());
  std::vector<std::unique_ptr<RcandProcess>> robots;
  for (const auto& name : kFleetNames)
    robots.push_back(std::make_unique<RcandProcess>(fleet_robot(name, token, broker.port(), peers_file)));
  REQUIRE(poll_until<bool>(
      [&]() -> std::optional<bool> {
        for (const auto& name : kFleetNames)
          if (wire.count(r2r_sent("status", name)) == 0) return std::nullopt;
        return true;
      },
      30s));

  // An operator's view of the broker (rcanctl r2r watch --mqtt, no robot token): on subscribing it is handed every
  // robot's retained status (r2r/status/<name>), and --count ends the watch.
  const auto watched = run_tool(
      rcanctl_binary(), {"r2r", "watch", "--mqtt", "127.0.0.1:" + std::to_string(broker.port()), "--count", "3", "--json"});
  REQUIRE_MESSAGE(watched.exit_code == 0, watched.err);
  std::set<std::string> statuses;
  std::istringstream lines(watched.out);
  for (std::string line; std::getline(lines, line);) {
    const json message = json::parse(line);
    CHECK(message["type"] == "status");
    statuses.insert(message["header"]["source_id"].get<std::string>());
  }
  CHECK(statuses == std::set<std::string>(kFleetNames.begin(), kFleetNames.end()));
  const auto misused = run_tool(rcanctl_binary(), {"r2r", "watch", "--username", "ops", "--token", "x"});
  CHECK(misused.exit_code == 2);
  CHECK(misused.err.find("need --mqtt") != std::string::npos);

  // An unsigned stop, and one signed by a key no robot enrolled: both broadcasts, both refused by every robot.
  auto rejected = [](const RcandProcess& robot) {
    return robot.json("GET", "/api/r2r/peers", "owner-token")["counters"]["rejected"].get<int>();
  };
  REQUIRE(wire.transport().send(r2r_message("ops", "command", {{"type", "estop"}, {"reason", "unsigned"}}), std::nullopt));
  json forged = json::parse(r2r_message("stranger", "command", {{"type", "estop"}, {"reason", "unenrolled"}}));
  rcand::r2r_wire::sign_message(forged, "stranger",
                                rcand::r2r_wire::Ed25519Key::private_from_file(std::filesystem::path(keys) / "stranger.key"));
  REQUIRE(wire.transport().send(forged.dump(), std::nullopt));
  const auto stranger_stop = fleet_tool({"stop", "--mqtt", "127.0.0.1:" + std::to_string(broker.port()), "--key",
                                         keys + "/stranger.key", "--name", "stranger", "--reason", "not yet"});
  CHECK(stranger_stop.exit_code == 0);  // the broker took it; no robot acts on it
  for (const auto& robot : robots) {
    REQUIRE(poll_until<bool>([&]() -> std::optional<bool> {
      if (rejected(*robot) >= 3) return true;
      return std::nullopt;
    }));
    CHECK_FALSE(fleet_latched(*robot));
    const std::string log = robot->stderr_text();
    CHECK(log.find("unauthorized fleet e-stop from 'ops' via mqtt") != std::string::npos);
    CHECK(log.find("unauthorized fleet e-stop from 'stranger' via mqtt: unknown signing key 'stranger'") != std::string::npos);
  }
  CHECK(wire.count(r2r_type("error")) == 0);  // a broadcast is never answered

  // A peers file broken on disk: the reload is refused with the file's line, the table in force stays.
  std::filesystem::copy_file(peers_file, peers_file + ".good");
  dir.write("fleet-peers.yaml", "peers:\n  - name: ops\n    public_key: not-a-key\n");
  ::kill(robots[0]->pid(), SIGHUP);
  INFO("alpha's log: " << robots[0]->stderr_text());
  CHECK(poll_until<bool>([&]() -> std::optional<bool> {
    if (robots[0]->stderr_text().find("fleet-peers.yaml:3:5: error: peers[0].public_key: expected a PEM Ed25519 key") !=
        std::string::npos)
      return true;
    return std::nullopt;
  }));
  std::filesystem::rename(peers_file + ".good", peers_file);

  // Enrolled, the file copied (here: shared) and every robot sent SIGHUP: the stranger is a peer now.
  REQUIRE(fleet_tool({"enroll", "--peers-file", peers_file, "stranger", keys + "/stranger.pub"}).exit_code == 0);
  for (const auto& robot : robots) {
    ::kill(robot->pid(), SIGHUP);
    REQUIRE(poll_until<bool>([&]() -> std::optional<bool> {
      if (robot->stderr_text().find("peers accepted") != std::string::npos) return true;
      return std::nullopt;
    }));
  }

  // The stop: signed with an enrolled key, acknowledged by the broker.
  const auto result = fleet_tool({"stop", "--mqtt", "127.0.0.1:" + std::to_string(broker.port()), "--key", keys + "/stranger.key",
                                  "--name", "stranger", "--reason", "aisle 3 blocked", "--json"});
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
    CHECK(estop["reason"] == "fleet e-stop from 'stranger': aisle 3 blocked");
    CHECK(estop["principal"] == "stranger");
    CHECK(estop["from"] == "r2r stranger");
    // Audited as the sender, as POST /api/stop.
    const json audit = robot.json("GET", "/api/audit?limit=20", "owner-token");
    bool audited = false;
    for (const auto& entry : audit["entries"])
      audited = audited || (entry.value("principal", "") == "stranger" && entry.value("event", "") == "POST /api/stop");
    CHECK(audited);
    // The latched status on the wire, long before the 60 s interval.
    const std::string& name = kFleetNames[i];
    CHECK(poll_until<bool>([&]() -> std::optional<bool> {
      const auto latched = [&](const std::string& topic, const json& m) {
        return r2r_sent("status", name)(topic, m) && m.contains("payload") && m["payload"].is_object() &&
               m["payload"].value("estopped", false);
      };
      if (wire.count(latched) > 0) return true;
      return std::nullopt;
    }));
  }
  CHECK(wire.count(r2r_type("error")) == 0);
}
