// UdpTransport on loopback: status datagrams to explicit destinations, nothing else goes out this way.
#include <doctest/doctest.h>
#include <nlohmann/json.hpp>

#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/udp.hpp>

#include <stdexcept>

#include "inbox.hpp"
#include "services/r2r/transports/udp_transport.hpp"
#include "wire_message.hpp"

using namespace rcand::services::r2r;
using nlohmann::json;

namespace {

using rcand::test::wire_message;

UdpOptions loopback(std::vector<UdpDestination> destinations = {}) {
  UdpOptions options;
  options.bind_address = "127.0.0.1";
  options.port = 0;
  options.destinations = std::move(destinations);
  return options;
}
}  // namespace

TEST_CASE("status broadcasts reach every destination as one datagram each; other messages are not sent") {
  UdpTransport b(loopback()), c(loopback());
  rcand::test::Inbox at_b, at_c;
  b.start(at_b.deliver());
  c.start(at_c.deliver());
  UdpTransport a(loopback({{"127.0.0.1", b.bound_port()}, {"127.0.0.1", c.bound_port()}}));
  rcand::test::Inbox at_a;
  a.start(at_a.deliver());

  CHECK(a.send(wire_message("status"), std::nullopt));
  const auto got_b = at_b.wait_for(1);
  const auto got_c = at_c.wait_for(1);
  REQUIRE(got_b.size() == 1);
  REQUIRE(got_c.size() == 1);
  CHECK(got_b[0].bytes == wire_message("status"));
  CHECK(got_b[0].transport == "udp");
  CHECK(got_b[0].peer == "127.0.0.1:" + std::to_string(a.bound_port()));
  CHECK_FALSE(got_b[0].reply);
  CHECK_FALSE(got_b[0].principal);

  CHECK_FALSE(a.send(wire_message("command"), std::nullopt));     // not status: WebSocket or MQTT carry it
  CHECK_FALSE(a.send(wire_message("status"), std::string("b")));  // no addressing by name over UDP
  CHECK(a.counters().sent == 2);
  a.stop();
  CHECK_FALSE(a.send(wire_message("status"), std::nullopt));
}

TEST_CASE("an oversize or garbage datagram is delivered as is: the node refuses it with code 100") {
  UdpTransport b(loopback());
  rcand::test::Inbox at_b;
  b.start(at_b.deliver());
  boost::asio::io_context io;
  boost::asio::ip::udp::socket raw(io, boost::asio::ip::udp::endpoint(boost::asio::ip::udp::v4(), 0));
  raw.send_to(boost::asio::buffer(std::string("garbage")), {boost::asio::ip::make_address("127.0.0.1"), b.bound_port()});
  const auto got = at_b.wait_for(1);
  REQUIRE(got.size() == 1);
  CHECK(got[0].bytes == "garbage");
}

TEST_CASE("destinations parse with a clear error") {
  CHECK(parse_udp_destination("255.255.255.255", "k").port == 0);
  CHECK(parse_udp_destination("10.0.0.7:9100", "k").port == 9100);
  CHECK(parse_udp_destination("[::1]:9100", "k").host == "::1");
  CHECK_THROWS_WITH_AS(parse_udp_destination("robot.local", "runtime.r2r.udp_broadcast[0]"),
                       "runtime.r2r.udp_broadcast[0]: 'robot.local' is not an IP address", std::invalid_argument);
  CHECK_THROWS_AS(parse_udp_destination("10.0.0.7:99999", "k"), std::invalid_argument);
  CHECK_THROWS_AS(parse_udp_destination("10.0.0.7:x", "k"), std::invalid_argument);
}

TEST_CASE("a port in use is a clear startup error") {
  rcand::test::Inbox inbox;
  // SO_REUSEADDR lets two UDP sockets share a port on Linux only when both set it; a foreign socket without it blocks.
  boost::asio::io_context io;
  boost::asio::ip::udp::socket holder(io, boost::asio::ip::udp::endpoint(boost::asio::ip::make_address("127.0.0.1"), 0));
  auto taken = loopback();
  taken.port = holder.local_endpoint().port();
  UdpTransport third(taken);
  CHECK_THROWS_WITH_AS(third.start(inbox.deliver()), doctest::Contains("runtime.r2r.udp_port: cannot bind UDP"),
                       std::runtime_error);
}
