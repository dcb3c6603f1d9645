#include "libs/isolation/channel.hpp"

#include <doctest/doctest.h>

#include <sys/socket.h>

#include <string>
#include <thread>

using nlohmann::json;
using rcand::isolation::Channel;

namespace {

struct Pair {
  Channel rcand_end, host_end;
  Pair() : Pair(Channel::socket_pair()) {}

 private:
  explicit Pair(std::pair<int, int> fds) : rcand_end(fds.first), host_end(fds.second) {}
};

}  // namespace

TEST_CASE("channel: each send is one message, received whole and in order") {
  Pair pair;
  const std::string big(Channel::kMaxMessage / 2, 'x');
  REQUIRE(pair.rcand_end.send({{"t", "a"}, {"n", 1}}));
  REQUIRE(pair.rcand_end.send({{"t", "b"}, {"text", big}}));
  REQUIRE(pair.rcand_end.send({{"t", "c"}, {"body", json::array({1, "two", nullptr})}}));
  CHECK(pair.host_end.receive()->at("n") == 1);
  CHECK(pair.host_end.receive()->at("text") == big);
  CHECK(pair.host_end.receive()->at("body") == json::array({1, "two", nullptr}));
}

TEST_CASE("channel: a message over the limit is refused at its sender, named, and the channel goes on") {
  Pair pair;
  std::string error;
  CHECK_FALSE(pair.host_end.send({{"t", "response"}, {"body", std::string(Channel::kMaxMessage + 1, 'x')}}, &error));
  CHECK(error.find("over the isolated channel's limit") != std::string::npos);
  REQUIRE(pair.host_end.send({{"t", "next"}}));
  CHECK(pair.rcand_end.receive()->at("t") == "next");
}

TEST_CASE("channel: a message that does not decode is skipped; a message without a type too") {
  Pair pair;
  const char garbage[] = "\xc1\xc1\xc1";  // 0xc1 is never used in MessagePack
  REQUIRE(::send(pair.rcand_end.fd(), garbage, 3, 0) == 3);
  REQUIRE(pair.rcand_end.send(json{{"no_type", true}}));
  REQUIRE(pair.rcand_end.send({{"t", "good"}}));
  CHECK(pair.host_end.receive()->at("t") == "good");
}

TEST_CASE("channel: the peer's end closing ends receive(); sends then fail") {
  auto fds = Channel::socket_pair();
  Channel rcand_end(fds.first);
  std::optional<json> received = json::object();
  std::thread reader([&] { received = rcand_end.receive(); });
  { Channel host_end(fds.second); }  // closed
  reader.join();
  CHECK_FALSE(received.has_value());
  std::string error;
  CHECK_FALSE(rcand_end.send({{"t", "x"}}, &error));
  CHECK(error == "the channel is closed");
}

TEST_CASE("channel: a send that must not wait fails at once when the peer stopped reading") {
  Pair pair;
  const std::string chunk(Channel::kMaxMessage / 4, 'x');
  std::string error;
  int sent = 0;
  while (pair.host_end.send({{"t", "log"}, {"text", chunk}}, &error, /*wait=*/false) && sent < 1000) ++sent;
  CHECK(sent < 1000);
  CHECK(error == "the peer is not reading");
}

TEST_CASE("channel: shutdown() wakes a blocked receive()") {
  Pair pair;
  std::optional<json> received = json::object();
  std::thread reader([&] { received = pair.rcand_end.receive(); });
  pair.rcand_end.shutdown();
  reader.join();
  CHECK_FALSE(received.has_value());
}
