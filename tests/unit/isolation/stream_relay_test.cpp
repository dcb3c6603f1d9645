// An isolated capability's stream routes, both ends in this process over a socket pair: the host's writer
// (remote_stream.hpp) driving the client's writer in rcand (stream_relay.hpp), frames through the ring.
#include <doctest/doctest.h>

#include <fcntl.h>
#include <unistd.h>

#include <rcand/sdk/testing/recording_stream.hpp>

#include <thread>

#include "eventually.hpp"
#include "libs/isolation/remote_stream.hpp"
#include "libs/isolation/stream_relay.hpp"

using namespace rcand::isolation;
using namespace std::chrono_literals;
using nlohmann::json;
using rcand::sdk::testing::RecordingStream;

namespace {

// rcand's end served by a relay, the host's by its streams: each end's reader as in rcand and the host.
struct Link {
  std::pair<int, int> fds = Channel::socket_pair();
  Channel rcand_end{fds.first}, host_end{fds.second};
  std::unique_ptr<FrameRing> rcand_ring = FrameRing::create(256 * 1024);
  std::unique_ptr<FrameRing> host_ring = FrameRing::attach(::fcntl(rcand_ring->fd(), F_DUPFD_CLOEXEC, 0));
  StreamRelay relay;
  RemoteStreams streams{host_end, host_ring.get()};
  std::thread rcand_reader{[this] {
    while (const auto message = rcand_end.receive())
      if (const auto answer = relay.deliver(*message, rcand_ring.get())) rcand_end.send(*answer);
  }};
  std::thread host_reader{[this] {
    while (const auto message = host_end.receive()) {
      if (message->at("t") == "s_started") streams.started(*message);
      if (message->at("t") == "s_state") streams.update(*message);
    }
    streams.close_all();
  }};
  // A client's writer in rcand, and the writer the host's plugin gets for it.
  std::pair<std::shared_ptr<RecordingStream>, std::shared_ptr<rcand::sdk::StreamWriter>> client() {
    auto recording = std::make_shared<RecordingStream>();
    return {recording, streams.open(relay.open(recording))};
  }
  ~Link() {
    rcand_end.shutdown();
    host_end.shutdown();
    rcand_reader.join();
    host_reader.join();
  }
};

rcand::sdk::SharedBytes jpeg(char fill) { return std::make_shared<const std::string>(20000, fill); }

}  // namespace

TEST_CASE(
    "streams: a multipart stream from the host reaches the client with its headers; counters and a leaving client "
    "come back") {
  Link link;
  const auto opened = link.client();  // not bound by name: the lambdas below capture them (clang 14)
  const auto& client = opened.first;
  const auto& writer = opened.second;
  REQUIRE(writer->start(200, "multipart/x-mixed-replace", {{"X-Accel-Buffering", "no"}}));
  CHECK(client->content_type() == "multipart/x-mixed-replace");
  CHECK(writer->push({jpeg('a'), "image/jpeg", {{"X-Timestamp-Us", "7"}}}));
  CHECK(writer->push({jpeg('b'), "image/jpeg", {}}));
  REQUIRE(client->wait_for_parts(2, 2s));
  CHECK(*client->parts()[0].data == std::string(20000, 'a'));
  CHECK(client->parts()[0].headers == rcand::sdk::Headers{{"X-Timestamp-Us", "7"}});
  CHECK(*client->parts()[1].data == std::string(20000, 'b'));

  // The heartbeat's state: the counters reach the host's writer; then the client leaves and the writer says closed.
  link.rcand_end.send(*link.relay.state());
  REQUIRE(rcand::test::eventually([&] { return writer->counters().sent == 2; }));
  client->close_client();
  link.rcand_end.send(*link.relay.state());
  REQUIRE(rcand::test::eventually([&] { return writer->closed(); }));
  CHECK_FALSE(writer->push({jpeg('c'), "image/jpeg", {}}));
  CHECK_FALSE(link.relay.state());  // forgotten in rcand
}

TEST_CASE(
    "streams: a snapshot's body through the ring, one too big for it inline, a JSON answer, and a start rcand "
    "refuses") {
  Link link;
  auto [snapshot, writer] = link.client();
  REQUIRE(writer->start(200, "image/jpeg", {{"Cache-Control", "no-store"}}));
  CHECK(writer->send(jpeg('s')));
  CHECK(writer->closed());  // the answer is complete
  REQUIRE(snapshot->wait_for_answer(2s));
  CHECK(snapshot->body() == std::string(20000, 's'));

  auto [big, big_writer] = link.client();
  REQUIRE(big_writer->start(200, "image/jpeg", {}));
  const auto huge = std::make_shared<const std::string>(link.host_ring->max_frame() + 1, 'h');
  CHECK(big_writer->send(huge));
  REQUIRE(big->wait_for_answer(2s));
  CHECK(big->body() == *huge);

  auto [refused, refused_writer] = link.client();
  CHECK(refused_writer->respond(rcand::sdk::Response::error(503, "SLOTS_RESERVED", "reserved"), {{"Retry-After", "1"}}));
  REQUIRE(refused->wait_for_answer(2s));
  CHECK(refused->status() == 503);
  CHECK(refused->json()["code"] == "SLOTS_RESERVED");

  auto gone = std::make_shared<RecordingStream>();
  const auto id = link.relay.open(gone);
  gone->close_client();  // rcand's caps, or a client that left: start() is false in the host, as in process
  CHECK_FALSE(link.streams.open(id)->start(200, "multipart/x-mixed-replace", {}));
}

TEST_CASE(
    "streams: when the host ends, clients not answered get rcand's 503 and streams end; a host's dropped writer "
    "is forgotten") {
  Link link;
  auto waiting = std::make_shared<RecordingStream>(), watching = std::make_shared<RecordingStream>();
  link.relay.open(waiting);
  {
    auto writer = link.streams.open(link.relay.open(watching));
    REQUIRE(writer->start(200, "multipart/x-mixed-replace", {}));
    auto dropped = link.streams.open(link.relay.open(std::make_shared<RecordingStream>()));
  }  // both host writers let go: rcand forgets both (its writers, dropped, end the stream or answer 500)
  REQUIRE(rcand::test::eventually([&] {
    const auto state = link.relay.state();
    return state && state->at("counters").size() == 1;  // only the one that never started
  }));
  link.relay.end_all(rcand::sdk::Response::error(503, "UNAVAILABLE", "its process ended"));
  CHECK(waiting->status() == 503);
  CHECK_FALSE(link.relay.state());
}
