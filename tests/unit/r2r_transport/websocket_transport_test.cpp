// WebSocketTransport through real sockets: an http::Server with the transport's upgrade hook, Beast clients, and two
// transports dialing each other. Bytes in, bytes out; the transport never interprets R2R.
#include <doctest/doctest.h>
#include <nlohmann/json.hpp>

#include <boost/asio/io_context.hpp>
#include <boost/beast/core/buffers_to_string.hpp>
#include <boost/beast/core/tcp_stream.hpp>
#include <boost/beast/websocket.hpp>

#include <chrono>
#include <memory>
#include <optional>
#include <string>
#include <thread>

#include "inbox.hpp"
#include "ws_client.hpp"
#include "rcand/kernel/auth/crypto.hpp"
#include "rcand/kernel/http/server.hpp"
#include "rcand/kernel/r2r_transport/websocket_transport.hpp"
#include "wire_message.hpp"

using namespace rcand::kernel;
using namespace std::chrono_literals;
using nlohmann::json;
namespace beast = boost::beast;
namespace websocket = boost::beast::websocket;
namespace net = boost::asio;

namespace {

using rcand::test::wire_message;

AuthSettings test_auth() {
  AuthSettings settings;
  settings.tokens.push_back({"peer-robot", rcand::sdk::Role::User, sha256_hex("peer-token")});
  settings.tokens.push_back({"watcher", rcand::sdk::Role::Guest, sha256_hex("guest-token")});
  return settings;
}

// A robot's HTTP side: the server with the WS upgrade hook; plain requests get 404.
struct Robot {
  Authenticator auth{test_auth()};
  std::unique_ptr<r2r::WebSocketTransport> transport;
  std::unique_ptr<http::Server> server;
  std::uint16_t port = 0;
  rcand::test::Inbox inbox;

  explicit Robot(std::string name, std::vector<swarm::SwarmNode> dial = {}) {
    r2r::WebSocketOptions options;
    options.self_name = std::move(name);
    options.dial_peers = std::move(dial);
    transport = std::make_unique<r2r::WebSocketTransport>(options, auth);
    http::ServerOptions server_options;
    server_options.upgrade = transport->upgrade_handler();
    server = std::make_unique<http::Server>(server_options, [](http::Request&&, http::Respond respond) {
      respond(http::error_response(404, "NOT_FOUND", "no such endpoint"));
    });
    port = server->start();
    transport->start(inbox.deliver());
  }
  ~Robot() {
    transport->stop();
    server->stop();
  }
};

using Client = rcand::test::WsClient;

}  // namespace

TEST_CASE("an authenticated peer exchanges frames with the transport, both ways, on one connection") {
  Robot robot("robot-a");
  Client client;
  REQUIRE(client.connect(robot.port, "peer-token") == 101);
  client.send(wire_message("status", "robot-b"));
  const auto got = robot.inbox.wait_for(1);
  REQUIRE(got.size() == 1);
  CHECK(got[0].bytes == wire_message("status", "robot-b"));
  CHECK(got[0].transport == "ws");
  REQUIRE(got[0].principal.has_value());
  CHECK(got[0].principal->name == "peer-robot");
  REQUIRE(got[0].reply);

  got[0].reply("answer on the same connection");
  CHECK(client.read() == "answer on the same connection");

  // The peer announced robot-b: it is now addressable by name, and reached by broadcasts.
  CHECK(robot.transport->send("to b by name", std::string("robot-b")));
  CHECK(client.read() == "to b by name");
  CHECK(robot.transport->send("to everyone", std::nullopt));
  CHECK(client.read() == "to everyone");
  CHECK_FALSE(robot.transport->send("to nobody", std::string("robot-z")));
  CHECK(robot.transport->connections()["connections"][0]["name"] == "robot-b");
}

TEST_CASE("an upgrade without valid credentials is refused with 401 and reaches nothing") {
  Robot robot("robot-a");
  Client anonymous;
  CHECK(anonymous.connect(robot.port, "") == 401);
  Client wrong;
  CHECK(wrong.connect(robot.port, "not-a-token") == 401);
  CHECK(robot.inbox.size() == 0);
  CHECK(robot.transport->counters().inbound_refused == 2);
  // Another path is not the transport's: the ordinary handler answers.
  Client elsewhere;
  CHECK(elsewhere.connect(robot.port, "peer-token", "/ws/other") == 404);
  // ?token= works where a client cannot set headers.
  Client query;
  CHECK(query.connect(robot.port, "", "/ws/r2r?token=guest-token") == 101);
}

TEST_CASE("a frame over 64 KiB closes the connection with 1009 and is never delivered") {
  Robot robot("robot-a");
  Client client;
  REQUIRE(client.connect(robot.port, "peer-token") == 101);
  client.send(wire_message("status", "robot-b", 70 * 1024));
  beast::error_code error;
  CHECK_FALSE(client.read(5s, &error).has_value());
  CHECK(error);  // closed (or a broken pipe when answering the close: the server has already dropped the socket)
  CHECK(client.ws.reason().code == websocket::close_code::too_big);
  CHECK(robot.inbox.size() == 0);
  const auto deadline = std::chrono::steady_clock::now() + 5s;
  while (robot.transport->counters().closed_oversize == 0 && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(5ms);  // the server counts after dropping the socket the client already saw close
  CHECK(robot.transport->counters().closed_oversize == 1);

  // A message just under the limit passes.
  Client fine;
  REQUIRE(fine.connect(robot.port, "peer-token") == 101);
  fine.send(wire_message("status", "robot-c", 60 * 1024));
  CHECK(robot.inbox.wait_for(1).size() == 1);
}

TEST_CASE("a robot dials a swarm peer it must reach, with the peer's token, and answers come back on that connection") {
  Robot b("robot-b");
  swarm::SwarmNode node;
  node.name = "robot-b";
  node.host = "127.0.0.1";
  node.port = b.port;
  node.token = "peer-token";
  Robot a("robot-a", {node});

  REQUIRE(a.transport->send(wire_message("command", "robot-a"), std::string("robot-b")));
  const auto at_b = b.inbox.wait_for(1);
  REQUIRE(at_b.size() == 1);
  CHECK(at_b[0].bytes == wire_message("command", "robot-a"));
  CHECK(at_b[0].principal->name == "peer-robot");  // b authenticated a with the token from a's swarm.yaml

  // b answers by name (a announced itself in its message) over the connection a opened.
  REQUIRE(b.transport->send(wire_message("task_response", "robot-b"), std::string("robot-a")));
  const auto at_a = a.inbox.wait_for(1);
  REQUIRE(at_a.size() == 1);
  CHECK(at_a[0].bytes == wire_message("task_response", "robot-b"));
  CHECK(a.transport->counters().dialed == 1);

  // A second message reuses the connection.
  REQUIRE(a.transport->send(wire_message("status", "robot-a"), std::string("robot-b")));
  CHECK(b.inbox.wait_for(2).size() == 2);
  CHECK(a.transport->counters().dialed == 1);
}

TEST_CASE("a dial to a dead peer fails, backs off, and never blocks the sender") {
  swarm::SwarmNode node;
  node.name = "robot-dead";
  node.host = "127.0.0.1";
  node.port = [] {
    net::io_context io;
    net::ip::tcp::acceptor acceptor(io, {net::ip::make_address("127.0.0.1"), 0});
    return acceptor.local_endpoint().port();
  }();
  node.token = "peer-token";
  Robot a("robot-a", {node});
  const auto started = std::chrono::steady_clock::now();
  CHECK(a.transport->send("x", std::string("robot-dead")));  // queued while dialing
  CHECK(std::chrono::steady_clock::now() - started < 100ms);
  const auto deadline = std::chrono::steady_clock::now() + 5s;
  while (a.transport->counters().dial_failed == 0 && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(5ms);  // polling a counter: the failure has no event to wait on
  CHECK(a.transport->counters().dial_failed == 1);
  CHECK_FALSE(a.transport->send("y", std::string("robot-dead")));  // in backoff: the node tries another transport
}

TEST_CASE("after stop nothing is delivered and upgrades answer 503") {
  Robot robot("robot-a");
  Client client;
  REQUIRE(client.connect(robot.port, "peer-token") == 101);
  robot.transport->stop();
  CHECK_FALSE(robot.transport->send("late", std::nullopt));
  beast::error_code error;
  CHECK_FALSE(client.read(5s, &error).has_value());  // the transport closed the connection
  Client late;
  CHECK(late.connect(robot.port, "peer-token") == 503);
  CHECK(robot.inbox.size() == 0);
}
