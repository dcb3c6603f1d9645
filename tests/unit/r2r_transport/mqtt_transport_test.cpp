// MqttTransport against a real mosquitto on loopback: topics r2r/<name> and r2r/broadcast, password auth, and a
// broker restart (the transport reconnects and resubscribes on its own).
#include <doctest/doctest.h>
#include <nlohmann/json.hpp>

#include <spdlog/logger.h>
#include <spdlog/sinks/ostream_sink.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include "eventually.hpp"
#include "inbox.hpp"
#include "mosquitto_broker.hpp"
#include "services/r2r/transports/mqtt_transport.hpp"
#include "wire_message.hpp"

using namespace rcand::services::r2r;
using namespace std::chrono_literals;
using nlohmann::json;

namespace {

using rcand::test::wire_message;

MqttOptions options_for(const std::string& name, std::uint16_t port) {
  MqttOptions options;
  options.robot_name = name;
  options.host = "127.0.0.1";
  options.port = port;
  options.keepalive_s = 5;
  return options;
}

using rcand::test::eventually;  // libmosquitto gives no event for the connected flag

}  // namespace

TEST_CASE("targeted messages reach r2r/<name> only; broadcasts reach everyone") {
  rcand::test::MosquittoBroker broker;
  MqttTransport a(options_for("robot-a", broker.port())), b(options_for("robot-b", broker.port())),
      c(options_for("robot-c", broker.port()));
  rcand::test::Inbox at_a, at_b, at_c;
  a.start(at_a.deliver());
  b.start(at_b.deliver());
  c.start(at_c.deliver());
  REQUIRE(eventually([&] { return a.connected() && b.connected() && c.connected(); }));
  // Subscriptions are acknowledged asynchronously: a broadcast seen by everyone proves they are in place.
  REQUIRE(eventually([&] {
    a.send(wire_message("task_request"), std::nullopt);
    return at_b.size() > 0 && at_c.size() > 0;
  }));
  REQUIRE(a.send(wire_message("command"), std::string("robot-b")));
  const auto got = at_b.wait_until([](const InboundMessage& m) { return m.bytes == wire_message("command"); });
  REQUIRE(got);
  CHECK(got->transport == "mqtt");
  CHECK(got->peer == "r2r/robot-b");
  CHECK_FALSE(got->reply);  // answers go through send() to r2r/<source_id>

  // A later broadcast reaches robot-c; robot-c never saw the command for robot-b (it arrived at robot-b first).
  REQUIRE(a.send(wire_message("negotiation"), std::nullopt));
  CHECK(at_c.wait_until([](const InboundMessage& m) { return m.bytes == wire_message("negotiation"); }));
  CHECK_FALSE(at_c.wait_until([](const InboundMessage& m) { return m.bytes == wire_message("command"); }, 0ms));

  // Names cannot smuggle topic wildcards or a NUL.
  CHECK_FALSE(a.send(wire_message("command"), std::string("robot-#")));
  CHECK_FALSE(a.send(wire_message("command"), std::string("robot-+")));
  CHECK_FALSE(a.send(wire_message("command"), std::string("robot\0b", 7)));
  CHECK_FALSE(a.send(wire_message("command"), std::string()));
}

TEST_CASE("status goes to r2r/status/<name>, retained, read only by its subscribers; a clean stop leaves offline there") {
  rcand::test::MosquittoBroker broker;
  auto reader_options = options_for("reader", broker.port());
  reader_options.status_subscriptions = {"robot-a"};
  auto fleet_options = options_for("fleet-view", broker.port());
  fleet_options.status_of_all = true;
  MqttTransport a(options_for("robot-a", broker.port())), b(options_for("robot-b", broker.port())), reader(reader_options),
      fleet_view(fleet_options);
  const std::string offline_bytes = wire_message("status", "robot-a-offline");  // the node's offline status, in short
  a.set_offline_status([&] { return offline_bytes; });
  rcand::test::Inbox at_b, at_reader, at_fleet;
  a.start([](InboundMessage) {});
  b.start(at_b.deliver());
  reader.start(at_reader.deliver());
  fleet_view.start(at_fleet.deliver());
  REQUIRE(eventually([&] { return a.connected() && b.connected() && reader.connected() && fleet_view.connected(); }));

  // Sent until the subscriptions are in place (acknowledged asynchronously).
  const auto is_status = [](const InboundMessage& m) { return m.bytes == wire_message("status"); };
  REQUIRE(eventually([&] {
    a.send(wire_message("status"), std::nullopt);
    return at_reader.size() > 0 && at_fleet.size() > 0;
  }));
  const auto got = at_reader.wait_until(is_status);
  REQUIRE(got);
  CHECK(got->peer == "r2r/status/robot-a");
  CHECK(got->broadcast);  // never answered with an error
  CHECK(got->status_topic);
  CHECK(at_fleet.wait_until(is_status));
  // robot-b reads no one's status: a broadcast sent after it arrives, the status never did.
  REQUIRE(a.send(wire_message("task_request"), std::nullopt));
  REQUIRE(at_b.wait_until([](const InboundMessage& m) { return m.bytes == wire_message("task_request"); }));
  CHECK_FALSE(at_b.wait_until(is_status, 0ms));

  // Retained: a reader that subscribes later gets the latest status at once, without waiting for the next one.
  auto late_options = reader_options;
  late_options.robot_name = "late-reader";  // a client id of its own: the broker would drop the other one
  MqttTransport late(late_options);
  rcand::test::Inbox at_late;
  late.start(at_late.deliver());
  CHECK(at_late.wait_until(is_status));
  late.stop();

  // A clean stop sends no will: the transport publishes the offline status itself, retained.
  a.stop();
  const auto offline = at_reader.wait_until([&](const InboundMessage& m) { return m.bytes == offline_bytes; });
  REQUIRE(offline);
  CHECK(offline->peer == "r2r/status/robot-a");
  late_options.robot_name = "later-reader";
  MqttTransport after(late_options);
  rcand::test::Inbox at_after;
  after.start(at_after.deliver());
  CHECK(at_after.wait_until([&](const InboundMessage& m) { return m.bytes == offline_bytes; }));
}

TEST_CASE("a peer whose id is a RURI gets its messages on r2r/<RURI> (topic levels are legal in an id)") {
  rcand::test::MosquittoBroker broker;
  const std::string ruri = "rcan://arm.local/acme/arm/4b1d";
  MqttTransport a(options_for("robot-a", broker.port())), peer(options_for(ruri, broker.port()));
  rcand::test::Inbox at_a, at_peer;
  a.start(at_a.deliver());
  peer.start(at_peer.deliver());
  REQUIRE(eventually([&] { return a.connected() && peer.connected(); }));
  // Subscriptions are acknowledged asynchronously: resend until the first one lands.
  REQUIRE(eventually([&] {
    REQUIRE(a.send(wire_message("command"), ruri));
    return at_peer.size() > 0;
  }));
  const auto got = at_peer.wait_until([](const InboundMessage& m) { return m.bytes == wire_message("command"); }, 0ms);
  REQUIRE(got);
  CHECK(got->peer == "r2r/" + ruri);
  CHECK(at_a.size() == 0);  // r2r/rcan:/... is not a's topic
}

TEST_CASE("a password-protected broker: right password connects, wrong one never does") {
  rcand::test::MosquittoBroker broker("robot-a", "s3cret-pass");
  const auto good_file = broker.dir() / "good.pw";
  const auto bad_file = broker.dir() / "bad.pw";
  std::ofstream(good_file) << "s3cret-pass\n";
  std::ofstream(bad_file) << "wrong\n";

  std::filesystem::permissions(good_file, std::filesystem::perms::owner_read | std::filesystem::perms::owner_write);
  std::filesystem::permissions(bad_file, std::filesystem::perms::others_read, std::filesystem::perm_options::add);
  std::ostringstream logged;
  auto log = std::make_shared<spdlog::logger>("mqtt", std::make_shared<spdlog::sinks::ostream_sink_mt>(logged));

  auto good_options = options_for("robot-a", broker.port());
  good_options.password_file = good_file;  // username defaults to the robot name
  good_options.log = log;
  MqttTransport good(good_options);
  rcand::test::Inbox inbox;
  good.start(inbox.deliver());
  CHECK(eventually([&] { return good.connected(); }));
  CHECK(logged.str().find("other users") == std::string::npos);  // mode 0600: nothing to say

  auto bad_options = options_for("robot-a", broker.port());
  bad_options.client_id = "rcand-robot-a-bad";
  bad_options.password_file = bad_file;
  bad_options.log = log;
  MqttTransport bad(bad_options);
  bad.start(inbox.deliver());
  CHECK_FALSE(eventually([&] { return bad.connected(); }, 1500ms));
  // Readable by others: named with the fix, the password itself never logged.
  CHECK(logged.str().find("runtime.r2r.mqtt.password_file: other users may read or write this secret") != std::string::npos);
  CHECK(logged.str().find("chmod 600") != std::string::npos);
  CHECK(logged.str().find("wrong") == std::string::npos);

  auto missing = options_for("robot-a", broker.port());
  missing.password_file = broker.dir() / "missing.pw";
  MqttTransport never(missing);
  CHECK_THROWS_WITH_AS(never.start(inbox.deliver()), doctest::Contains("runtime.r2r.mqtt.password_file: cannot read"),
                       std::runtime_error);
}

TEST_CASE("the transport survives a broker restart: it reconnects and resubscribes by itself") {
  rcand::test::MosquittoBroker broker;
  MqttTransport a(options_for("robot-a", broker.port())), b(options_for("robot-b", broker.port()));
  rcand::test::Inbox at_a, at_b;
  a.start(at_a.deliver());
  b.start(at_b.deliver());
  REQUIRE(eventually([&] { return a.connected() && b.connected(); }));
  broker.stop();
  REQUIRE(eventually([&] { return !a.connected() && !b.connected(); }));
  broker.start();
  REQUIRE(eventually([&] { return a.connected() && b.connected(); }, 40s));
  CHECK(eventually([&] {
    a.send(wire_message("command"), std::string("robot-b"));
    return at_b.size() > 0;
  }));
  CHECK(b.counters().connects >= 2);
}

TEST_CASE("a broker that is down at start is not fatal: the transport connects when it appears") {
  const auto port = rcand::test::free_tcp_port();
  MqttTransport a(options_for("robot-a", port));
  rcand::test::Inbox inbox;
  CHECK_NOTHROW(a.start(inbox.deliver()));
  CHECK_FALSE(a.connected());
  a.stop();
}

TEST_CASE("runtime.r2r.mqtt is read with errors naming the key") {
  const auto options = mqtt_options_from_config(
      json{{"host", "broker.lan"}, {"port", 1884}, {"username", "u"}, {"token_file", "r2r.token"}, {"keepalive_s", 10}},
      "robot-a", "/etc/rcand");
  CHECK(options.host == "broker.lan");
  CHECK(options.port == 1884);
  CHECK(options.token_file == std::filesystem::path("/etc/rcand/r2r.token"));
  CHECK(mqtt_options_from_config(json{{"tls", {{"ca_file", "/ca.pem"}}}}, "r", "/").port == 8883);
  CHECK_THROWS_WITH_AS(mqtt_options_from_config(json{{"port", 0}}, "r", "/"),
                       "runtime.r2r.mqtt.port: expected an integer from 1 to 65535", std::invalid_argument);
  CHECK_THROWS_WITH_AS(mqtt_options_from_config(json{{"tls", {{"cert_file", "c.pem"}}}}, "r", "/"),
                       "runtime.r2r.mqtt.tls.ca_file: required for TLS", std::invalid_argument);
  CHECK_THROWS_AS(mqtt_options_from_config(json{{"password_file", "p"}, {"token_file", "t"}}, "r", "/"), std::invalid_argument);
  CHECK(mqtt_options_from_config(json{{"status_subscriptions", "all"}}, "r", "/").status_of_all);
  CHECK(mqtt_options_from_config(json{{"status_subscriptions", {"a", "b"}}}, "r", "/").status_subscriptions ==
        std::vector<std::string>{"a", "b"});
  CHECK_FALSE(mqtt_options_from_config(json::object(), "r", "/").status_of_all);
  CHECK_THROWS_WITH_AS(mqtt_options_from_config(json{{"status_subscriptions", {"a", "+"}}}, "r", "/"),
                       "runtime.r2r.mqtt.status_subscriptions: expected robot names (no '+' or '#'), or all",
                       std::invalid_argument);
  CHECK_THROWS_AS(mqtt_options_from_config(json{{"status_subscriptions", "some"}}, "r", "/"), std::invalid_argument);
}
