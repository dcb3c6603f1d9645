// WebSocketTransport through real sockets: an http::Server with the transport's upgrade hook, Beast clients, and two
// transports dialing each other. Bytes in, bytes out; the transport never interprets R2R.
#include <doctest/doctest.h>
#include <nlohmann/json.hpp>

#include <boost/asio/io_context.hpp>
#include <boost/beast/core/buffers_to_string.hpp>
#include <boost/beast/core/tcp_stream.hpp>
#include <boost/beast/websocket.hpp>

#include <chrono>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <thread>

#include "eventually.hpp"
#include "inbox.hpp"
#include "libs/http/server.hpp"
#include "libs/rcan/crypto.hpp"
#include "libs/rcan/jwt.hpp"
#include "services/r2r/transports/websocket_transport.hpp"
#include "tls_lab.hpp"
#include "wire_message.hpp"
#include "ws_client.hpp"

using namespace rcand;
using namespace rcand::kernel;
using namespace rcand::services;
using namespace std::chrono_literals;
using nlohmann::json;
namespace beast = boost::beast;
namespace websocket = boost::beast::websocket;
namespace net = boost::asio;

namespace {

using rcand::test::wire_message;

constexpr const char* kWsJwtSecret = "ws-test-jwt-secret-0123456789";

AuthSettings test_auth() {
  AuthSettings settings;
  settings.tokens.push_back({"peer-robot", rcand::sdk::Role::User, sha256_hex("peer-token")});
  settings.tokens.push_back({"watcher", rcand::sdk::Role::Guest, sha256_hex("guest-token")});
  settings.tokens.push_back({"operator", rcand::sdk::Role::Owner, sha256_hex("owner-token")});
  settings.jwt_secret = kWsJwtSecret;
  settings.robot_ruri = "rcan://acme.rover.1a2b3c4d";
  settings.device_id = "1a2b3c4d";
  return settings;
}

// A robot's HTTP side: the server with the WS upgrade hook; plain requests get 404.
struct Robot {
  Authenticator auth{test_auth()};
  swarm::SwarmRegistry peers;  // what this robot dials
  std::unique_ptr<r2r::WebSocketTransport> transport;
  std::unique_ptr<http::Server> server;
  std::uint16_t port = 0;
  rcand::test::Inbox inbox;

  explicit Robot(std::string name, std::vector<swarm::SwarmNode> dial = {},
                 const std::function<void(r2r::WebSocketOptions&)>& adjust = {}, std::optional<http::TlsSettings> tls = {}) {
    r2r::WebSocketOptions options;
    options.self_name = std::move(name);
    peers.nodes = std::move(dial);
    if (!peers.nodes.empty()) options.dial_peers = [this] { return &peers; };
    if (adjust) adjust(options);
    transport = std::make_unique<r2r::WebSocketTransport>(options, auth);
    http::ServerOptions server_options;
    server_options.upgrade = transport->upgrade_handler();
    server_options.tls = std::move(tls);  // set: this robot serves wss only (plain HTTP on another loopback port)
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

using rcand::test::eventually;  // a dial's failure has no event of its own

// robot-b serving wss only, with a certificate for 127.0.0.1 that the lab's CA signed.
http::TlsSettings wss_only(const rcand::test::TlsLab& lab) {
  http::TlsSettings tls;
  tls.cert_file = lab.pem("server");
  tls.key_file = lab.key("server");
  return tls;
}

swarm::SwarmNode node_b(std::uint16_t port, std::optional<std::filesystem::path> ca) {
  swarm::SwarmNode node;
  node.name = "robot-b";
  node.host = "127.0.0.1";
  node.port = port;
  node.token = "peer-token";
  node.ca = std::move(ca);
  return node;
}

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

TEST_CASE("a robot dials a TLS-only peer over wss, its certificate checked against the node's ca") {
  rcand::test::TlsLab lab;
  Robot b("robot-b", {}, {}, wss_only(lab));
  Robot a("robot-a", {node_b(b.port, lab.pem("ca"))});

  REQUIRE(a.transport->send(wire_message("command", "robot-a"), std::string("robot-b")));
  const auto at_b = b.inbox.wait_for(1);
  REQUIRE(at_b.size() == 1);
  CHECK(at_b[0].bytes == wire_message("command", "robot-a"));
  CHECK(at_b[0].principal->name == "peer-robot");
  REQUIRE(b.transport->send(wire_message("task_response", "robot-b"), std::string("robot-a")));
  const auto at_a = a.inbox.wait_for(1);
  REQUIRE(at_a.size() == 1);
  CHECK(at_a[0].bytes == wire_message("task_response", "robot-b"));
  CHECK(a.transport->counters().dialed == 1);
  CHECK(a.transport->counters().dial_failed == 0);
}

TEST_CASE("a wss dial is refused before anything is sent when the peer's certificate fails the check") {
  rcand::test::TlsLab lab;
  Robot b("robot-b", {}, {}, wss_only(lab));
  SUBCASE("signed by a CA the node's ca is not") {
    Robot a("robot-a", {node_b(b.port, lab.pem("other-ca"))});
    CHECK(a.transport->send("x", std::string("robot-b")));  // queued while dialing
    CHECK(eventually([&] { return a.transport->counters().dial_failed == 1; }));
    CHECK_FALSE(a.transport->send("y", std::string("robot-b")));  // in backoff: the next transport is tried
  }
  SUBCASE("a plain dial (no ca) to a wss-only peer") {
    Robot a("robot-a", {node_b(b.port, std::nullopt)});
    CHECK(a.transport->send("x", std::string("robot-b")));
    CHECK(eventually([&] { return a.transport->counters().dial_failed == 1; }));
  }
  SUBCASE("a ca file that cannot be read: no connection at all") {
    Robot a("robot-a", {node_b(b.port, lab.dir() / "missing-ca.pem")});
    CHECK_FALSE(a.transport->send("x", std::string("robot-b")));
    CHECK(a.transport->counters().dial_failed == 1);
    CHECK(a.transport->counters().dialed == 0);
  }
  // The token never reached robot-b: it authorized no upgrade and nothing was delivered.
  CHECK(b.transport->counters().inbound_accepted == 0);
  CHECK(b.inbox.size() == 0);
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
  CHECK(eventually([&] { return a.transport->counters().dial_failed == 1; }));
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

namespace {

// The close code a client saw, once the connection ended (0 while it is open, or when it timed out).
int close_code_seen(Client& client, std::chrono::milliseconds within) {
  const auto deadline = std::chrono::steady_clock::now() + within;
  while (std::chrono::steady_clock::now() < deadline) {
    beast::error_code error;
    if (client.read(std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now()), &error))
      continue;  // a frame: keep reading
    if (error == websocket::error::closed) return static_cast<int>(client.ws.reason().code);
    return 0;
  }
  return 0;
}

}  // namespace

TEST_CASE("a socket whose token a config reload removed is closed (1008) at its next frame, in or out") {
  Robot robot("robot-a");
  Client watcher;
  REQUIRE(watcher.connect(robot.port, "guest-token") == 101);
  Client peer;
  REQUIRE(peer.connect(robot.port, "peer-token") == 101);
  auto reloaded = test_auth();
  reloaded.tokens.erase(reloaded.tokens.begin() + 1);  // the watcher's token is gone (SIGHUP)
  robot.auth.replace(reloaded);
  CHECK(robot.transport->send(wire_message("robot-a", "status"), std::nullopt));  // a broadcast: re-checked first
  CHECK(close_code_seen(watcher, 5s) == 1008);
  peer.send(wire_message("peer-robot", "status"));  // the peer's token still holds: its frame is delivered
  CHECK(robot.inbox.wait_for(1).size() == 1);
  CHECK(robot.transport->counters().closed_credentials == 1);
}

TEST_CASE("a socket opened with a JWT is closed (1008) when the JWT expires, even when nothing is sent") {
  Robot robot("robot-a");
  JwtClaims claims;
  claims.sub = "short-lived";
  claims.iss = "test";
  claims.role = "user";
  claims.aud = {"rcan://*"};
  claims.scope = {"status", "control"};
  claims.iat = std::chrono::duration_cast<std::chrono::seconds>(std::chrono::system_clock::now().time_since_epoch()).count();
  claims.exp = claims.iat - kJwtExpLeewayS + 2;  // good for 2 more seconds, leeway included
  Client holder;
  REQUIRE(holder.connect(robot.port, issue_jwt_hs256(claims, kWsJwtSecret)) == 101);
  const auto opened = std::chrono::steady_clock::now();
  CHECK(close_code_seen(holder, 10s) == 1008);
  CHECK(std::chrono::steady_clock::now() - opened >= 1s);  // at expiry, not at once
  CHECK(robot.transport->counters().closed_credentials == 1);
}

TEST_CASE("below OWNER a principal holds a few sockets at most, and the last slots are the owners'") {
  Robot robot("robot-a", {}, [](r2r::WebSocketOptions& options) {
    options.max_connections = 6;
    options.reserved_connections = 2;
    options.max_connections_per_principal = 3;
  });
  std::vector<std::unique_ptr<Client>> held;
  auto open = [&](const std::string& token) {
    held.push_back(std::make_unique<Client>());
    return held.back()->connect(robot.port, token);
  };
  for (int i = 0; i < 3; ++i) CHECK(open("guest-token") == 101);
  CHECK(open("guest-token") == 429);  // the guest's cap: TOO_MANY_CONNECTIONS
  CHECK(open("peer-token") == 101);   // 4 of 6: the rest are reserved
  CHECK(open("peer-token") == 503);
  CHECK(open("owner-token") == 101);  // an owner gets in regardless
  CHECK(open("owner-token") == 101);
  CHECK(open("owner-token") == 503);  // max_connections
}

TEST_CASE("a client that does not read is dropped once its queue passes max_queued_bytes") {
  Robot robot("robot-a", {}, [](r2r::WebSocketOptions& options) { options.max_queued_bytes = 256 * 1024; });
  Client sleeper;
  REQUIRE(sleeper.connect(robot.port, "guest-token") == 101);  // and never reads
  const std::string big(60 * 1024, 'x');
  for (int i = 0; i < 400 && !robot.transport->connections()["connections"].empty(); ++i) {
    robot.transport->send(big, std::nullopt);
    const auto open = robot.transport->connections();  // kept: the loop below reads into it
    for (const auto& connection : open["connections"]) CHECK(connection["queued_bytes"].get<std::size_t>() <= 256 * 1024);
  }
  const auto deadline = std::chrono::steady_clock::now() + 5s;
  while (!robot.transport->connections()["connections"].empty() && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(5ms);                            // the close completes on the server's loop: polled, bounded
  CHECK(robot.transport->connections()["connections"].empty());  // 24 MB offered: dropped, not queued
}

TEST_CASE("this robot's token goes only to connections trusted with it: an OWNER client, never a guest") {
  Robot robot("robot-a");
  Client guest, owner;
  REQUIRE(guest.connect(robot.port, "guest-token") == 101);
  REQUIRE(owner.connect(robot.port, "owner-token") == 101);
  CHECK(robot.transport->send_own("with-token", "open", std::nullopt));
  CHECK(guest.read() == std::optional<std::string>("open"));
  CHECK(owner.read() == std::optional<std::string>("with-token"));
}
