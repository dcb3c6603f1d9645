// R2R among several real rcand processes: auctions over WebSocket (robots dial their swarm.yaml peers) award the
// nearest capable robot and re-award when the winner dies; over MQTT (a real mosquitto the test starts) every message
// type round-trips and errors travel back to their sender; UDP carries status between robots.
#include <doctest/doctest.h>

#include <signal.h>

#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/udp.hpp>

#include <algorithm>
#include <chrono>
#include <mutex>

#include "libs/r2r_wire/message_signature.hpp"
#include "mosquitto_broker.hpp"
#include "r2r_lab.hpp"
#include "rcand_process.hpp"
#include "services/r2r/transports/mqtt_transport.hpp"

using namespace rcand::test;
using nlohmann::json;
using namespace std::chrono_literals;

namespace {

json bidders_of(const json& result) {
  json names = json::array();
  for (const auto& bid : result["bids"]) names.push_back(bid["bidder"]);
  return names;
}

std::uint16_t free_udp_port() {
  boost::asio::io_context io;
  boost::asio::ip::udp::socket socket(io, boost::asio::ip::udp::endpoint(boost::asio::ip::make_address("127.0.0.1"), 0));
  return socket.local_endpoint().port();
}

}  // namespace

TEST_CASE("r2r fleet (ws): the nearest capable robot wins; when the winner dies mid-auction the task is re-awarded") {
  TempDir dir;
  const auto token = dir.write("r2r.token", "owner-token\n");
  RcandProcess bravo(r2r_robot_config("bravo", token, 1.0, 0.0));
  RcandProcess charlie(r2r_robot_config("charlie", token, 4.0, 0.0));
  auto delta_config = r2r_robot_config("delta", token, 0.2, 0.0);  // nearest, but cannot drive: never bids
  delta_config["rcan_protocol"]["capabilities"] = {"status", "com.acme.gripper"};
  RcandProcess delta(delta_config);
  const auto swarm_file = dir.write("swarm.yaml", swarm_yaml({{"bravo", "127.0.0.1", bravo.port()},
                                                              {"charlie", "127.0.0.1", charlie.port()},
                                                              {"delta", "127.0.0.1", delta.port()}}));
  RcandProcess alpha(r2r_robot_config("alpha", token, 0.0, 0.0, swarm_file));

  const json task{
      {"description", "fetch the box"}, {"required_capabilities", {"teleop"}}, {"location", {{"x", 0.0}, {"y", 0.0}}}};
  int status = 0;
  const auto result = alpha.json("POST", "/api/r2r/auction", "user-token", task.dump(), &status);
  REQUIRE(status == 200);
  CHECK(result["decided"] == true);
  CHECK(result["state"] == "assigned");
  CHECK(result["winner"] == "bravo");
  CHECK(result["estimated_time"].is_number());
  const auto bidders = bidders_of(result);
  CHECK(bidders.size() == 2);
  CHECK(std::find(bidders.begin(), bidders.end(), "delta") == bidders.end());
  const auto held = bravo.json("GET", "/api/r2r/peers", "guest-token")["held_tasks"];
  REQUIRE(held.size() == 1);
  CHECK(held[0]["requester"] == "alpha");

  // Second task: bravo dies after bidding, before the award. Its award goes unanswered, the silent winner is timed
  // out (bid_deadline + 2 s) and charlie gets the task.
  auto second = task;
  second["task_id"] = "T-rescue";
  second["wait"] = false;
  alpha.json("POST", "/api/r2r/auction", "user-token", second.dump(), &status);
  REQUIRE(status == 202);
  REQUIRE(poll_until<bool>([&]() -> std::optional<bool> {
    const auto bids = bidders_of(alpha.json("GET", "/api/r2r/auction/T-rescue", "guest-token"));
    if (std::find(bids.begin(), bids.end(), "bravo") != bids.end()) return true;
    return std::nullopt;
  }));
  ::kill(bravo.pid(), SIGKILL);
  const auto rescued = poll_until<json>(
      [&]() -> std::optional<json> {
        auto doc = alpha.json("GET", "/api/r2r/auction/T-rescue", "guest-token");
        if (doc["state"] == "assigned") return doc;
        return std::nullopt;
      },
      15s);
  REQUIRE(rescued);
  INFO("auction: " << rescued->dump());
  CHECK((*rescued)["winner"] == "charlie");
}

TEST_CASE("r2r fleet (mqtt): status, auction, command and errors round-trip through a real broker") {
  MosquittoBroker broker;
  TempDir dir;
  const auto token = dir.write("r2r.token", "owner-token\n");
  auto with_mqtt = [&](json config) {
    config["runtime"]["r2r"]["mqtt"] = {
        {"host", "127.0.0.1"}, {"port", broker.port()}, {"keepalive_s", 5}, {"status_subscriptions", "all"}};
    return config;
  };
  auto bravo_config = with_mqtt(r2r_robot_config("bravo", token, 2.0, 0.0));
  auto alpha_config = with_mqtt(r2r_robot_config("alpha", token, 0.0, 0.0));
  sign_fleet({&bravo_config, &alpha_config}, dir);
  RcandProcess bravo(bravo_config);
  RcandProcess alpha(alpha_config);

  // An observer on r2r/# sees the fleet's traffic, as `rcanctl r2r watch` does.
  rcand::services::r2r::MqttOptions observer_options;
  observer_options.robot_name = "observer";
  observer_options.host = "127.0.0.1";
  observer_options.port = broker.port();
  observer_options.extra_subscriptions = {"r2r/#"};
  rcand::services::r2r::MqttTransport observer(observer_options);
  std::mutex seen_mutex;
  std::vector<json> seen;
  observer.start([&](rcand::services::r2r::InboundMessage message) {
    std::lock_guard lock(seen_mutex);
    seen.push_back(json::parse(message.bytes, nullptr, false));
  });
  auto seen_where = [&](const std::function<bool(const json&)>& match) {
    return poll_until<json>([&]() -> std::optional<json> {
      std::lock_guard lock(seen_mutex);
      for (const auto& m : seen)
        if (m.is_object() && match(m)) return m;
      return std::nullopt;
    });
  };

  // status: each robot reads the other's on r2r/status/<name> (status_subscriptions: all).
  const auto heard = poll_until<json>([&] { return peer_status_placed(alpha, "bravo"); });
  REQUIRE(heard);
  CHECK((*heard)["transport"] == "mqtt");
  CHECK((*heard)["status"]["position"]["x"] == doctest::Approx(2.0));
  const auto caps = (*heard)["status"]["capabilities"];
  CHECK(std::find(caps.begin(), caps.end(), "teleop") != caps.end());

  // task_request / negotiation bid + award / task_response.
  int status = 0;
  const auto result = alpha.json(
      "POST", "/api/r2r/auction", "user-token",
      json{{"task_id", "M1"}, {"required_capabilities", {"teleop"}}, {"location", {{"x", 2.5}, {"y", 0}}}}.dump(), &status);
  REQUIRE(status == 200);
  CHECK(result["winner"] == "bravo");
  CHECK(seen_where([](const json& m) { return m["type"] == "task_response" && m["payload"]["task_id"] == "M1"; }));
  // No token rides over MQTT (anyone on the broker would see it): the robots' messages are signed instead.
  {
    std::lock_guard lock(seen_mutex);
    for (const auto& m : seen)
      if (m.is_object() && m["header"].is_object()) {
        CHECK_FALSE(m["header"].contains("auth"));
        CHECK(m["header"].contains("signature"));
      }
  }

  // command: moves bravo; then bravo is e-stopped and the next command comes back to alpha as error 105.
  alpha.json("POST", "/api/r2r/send", "user-token",
             json{{"type", "command"},
                  {"target", "bravo"},
                  {"payload", {{"type", "move"}, {"linear", 0.3}, {"angular", 0.0}, {"duration_ms", 3000}}}}
                 .dump(),
             &status);
  REQUIRE(status == 200);
  CHECK(poll_until<bool>([&]() -> std::optional<bool> {
    if (drive_status(bravo)["moving"] == true) return true;
    return std::nullopt;
  }));
  bravo.json("POST", "/api/stop", "guest-token", "", &status);
  alpha.json("POST", "/api/r2r/send", "user-token",
             json{{"type", "command"},
                  {"target", "bravo"},
                  {"payload", {{"type", "move"}, {"linear", 0.3}, {"angular", 0.0}, {"duration_ms", 3000}}}}
                 .dump(),
             &status);
  const auto refused = seen_where([](const json& m) {
    return m["type"] == "error" && m["payload"]["code"] == 105 && m["header"].value("target_id", "") == "alpha";
  });
  REQUIRE(refused);
  CHECK(drive_status(bravo)["moving"] == false);

  // 101: a message (with the fleet token) for a robot that is not there, published by hand onto bravo's topic.
  json lost = json::parse(r2r_message("observer", "command", {{"type", "stop"}}, std::string("nobody")));
  lost["header"]["auth"] = {{"token", "owner-token"}};
  REQUIRE(observer.send(lost.dump(), std::string("bravo")));
  CHECK(seen_where([](const json& m) {
    return m["type"] == "error" && m["payload"]["code"] == 101 && m["header"].value("target_id", "") == "observer";
  }));
  // Without a token it is refused as 103 before its target is even looked at.
  REQUIRE(observer.send(r2r_message("observer", "command", {{"type", "stop"}}, std::string("bravo")), std::string("bravo")));
  CHECK(seen_where([](const json& m) {
    return m["type"] == "error" && m["payload"]["code"] == 103 && m["header"].value("target_id", "") == "observer";
  }));
  observer.stop();
}

TEST_CASE("r2r fleet (udp): status datagrams reach the robots listed; garbage datagrams do no harm") {
  TempDir dir;
  const auto token = dir.write("r2r.token", "owner-token\n");
  const auto bravo_udp = free_udp_port();
  auto bravo_config = r2r_robot_config("bravo", token, 7.0, 1.0);
  bravo_config["runtime"]["r2r"]["udp_enabled"] = true;
  bravo_config["runtime"]["r2r"]["udp_port"] = bravo_udp;
  bravo_config["runtime"]["r2r"]["udp_broadcast"] = json::array();
  auto alpha_config = r2r_robot_config("alpha", token, -3.0, 0.0);
  alpha_config["runtime"]["r2r"]["udp_enabled"] = true;
  alpha_config["runtime"]["r2r"]["udp_port"] = 0;
  alpha_config["runtime"]["r2r"]["udp_broadcast"] = {"127.0.0.1:" + std::to_string(bravo_udp)};
  sign_fleet({&bravo_config, &alpha_config}, dir);
  RcandProcess bravo(bravo_config);
  RcandProcess alpha(alpha_config);

  const auto heard = poll_until<json>([&] { return peer_status_placed(bravo, "alpha"); });
  REQUIRE(heard);
  CHECK((*heard)["transport"] == "udp");
  CHECK((*heard)["status"]["position"]["x"] == doctest::Approx(-3.0));

  boost::asio::io_context io;
  boost::asio::ip::udp::socket raw(io, boost::asio::ip::udp::endpoint(boost::asio::ip::udp::v4(), 0));
  for (const std::string garbage : {"", "{", "[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[", "{\"header\":1}"})
    raw.send_to(boost::asio::buffer(garbage), {boost::asio::ip::make_address("127.0.0.1"), bravo_udp});
  raw.send_to(boost::asio::buffer(std::string(60000, '{')), {boost::asio::ip::make_address("127.0.0.1"), bravo_udp});
  CHECK(poll_until<bool>([&]() -> std::optional<bool> {
    if (bravo.json("GET", "/api/r2r/peers", "guest-token")["counters"]["rejected"].get<int>() >= 4) return true;
    return std::nullopt;
  }));
  CHECK(bravo.json("GET", "/health")["status"] == "ok");
}
