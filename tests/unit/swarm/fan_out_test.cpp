// The parallel fan-out against real servers on loopback: a peer that refuses, one that accepts and never answers,
// slow ones and name resolution with the ip fallback. A dead peer must never delay the others.
#include <doctest/doctest.h>
#include <nlohmann/json.hpp>

#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <future>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

#include "libs/http/server.hpp"
#include "libs/swarm/fan_out.hpp"
#include "streaming_peer.hpp"

using namespace rcand;
using namespace std::chrono_literals;
using nlohmann::json;
using boost::asio::ip::tcp;

namespace {

struct Peer {
  std::unique_ptr<http::Server> server;
  std::uint16_t port = 0;
  // Echoes what it received; answers after `delay` from a thread of its own (a slow robot).
  explicit Peer(std::chrono::milliseconds delay = 0ms) {
    http::ServerOptions options;
    options.address = "127.0.0.1";
    options.port = 0;
    server = std::make_unique<http::Server>(options, [delay](http::Request&& request, http::Respond respond) {
      http::Response response;
      response.body = json{{"method", request.method}, {"path", request.path}, {"body", request.body},
                           {"authorization", request.header("authorization").value_or("")},
                           {"forwarded", request.header("x-swarm-forwarded").value_or("")}}
                          .dump();
      if (delay.count() == 0) return respond(std::move(response));
      std::thread([delay, respond, response]() mutable {
        std::this_thread::sleep_for(delay);  // the simulated peer's own processing time
        respond(std::move(response));
      }).detach();
    });
    port = server->start();
  }
};

// A port that completes the TCP handshake (the kernel's backlog) and never answers.
struct BlackHole {
  boost::asio::io_context io;
  tcp::acceptor acceptor{io, tcp::endpoint(tcp::v4(), 0)};
  std::uint16_t port() const { return acceptor.local_endpoint().port(); }
};

// A port nobody listens on.
std::uint16_t closed_port() {
  boost::asio::io_context io;
  tcp::acceptor acceptor(io, tcp::endpoint(boost::asio::ip::make_address("127.0.0.1"), 0));
  return acceptor.local_endpoint().port();
}

swarm::PeerRequest to(const std::string& name, std::uint16_t port, const std::string& host = "127.0.0.1") {
  swarm::PeerRequest request;
  request.name = name;
  request.host = host;
  request.port = port;
  request.method = "POST";
  request.target = "/api/stop";
  request.body = R"({"reason":"test"})";
  request.headers = {{"Authorization", "Bearer token-of-" + name}, {"X-Swarm-Forwarded", "rcan://origin"}};
  return request;
}

}  // namespace

TEST_CASE("every peer gets its own request; dead and silent peers fail alone, within the deadline") {
  Peer a, b;
  BlackHole silent;
  const auto refused = closed_port();
  swarm::FanOut fan_out;
  const auto before = std::chrono::steady_clock::now();
  auto results = fan_out.run_and_wait({to("a", a.port), to("silent", silent.port()), to("refused", refused), to("b", b.port)}, 300ms);
  const auto elapsed = std::chrono::steady_clock::now() - before;
  REQUIRE(results.size() == 4);

  for (int i : {0, 3}) {
    const auto& r = results[i];
    CHECK(r.reachable);
    CHECK(r.status == 200);
    CHECK(r.error.empty());
    CHECK(r.address == "127.0.0.1:" + std::to_string(i == 0 ? a.port : b.port));
    auto seen = json::parse(r.body);
    CHECK(seen["method"] == "POST");
    CHECK(seen["path"] == "/api/stop");
    CHECK(seen["body"] == R"({"reason":"test"})");
    CHECK(seen["authorization"] == "Bearer token-of-" + r.name);
    CHECK(seen["forwarded"] == "rcan://origin");
    CHECK(r.latency_ms < 250.0);  // not held back by the silent peer (generous margin under its 300 ms deadline)
  }
  CHECK(results[0].name == "a");
  CHECK(results[1].name == "silent");
  CHECK_FALSE(results[1].reachable);
  CHECK(results[1].error.find("timed out after 300 ms") != std::string::npos);
  CHECK(results[1].latency_ms >= 299.0);
  CHECK_FALSE(results[2].reachable);
  CHECK(results[2].error.find("cannot connect to 127.0.0.1:" + std::to_string(refused)) == 0);
  CHECK(results[2].error.find("refused") != std::string::npos);
  CHECK(elapsed < 500ms);  // §15.5: the whole broadcast stays inside the stop budget
}

TEST_CASE("slow peers are served in parallel, not one after another") {
  std::vector<std::unique_ptr<Peer>> peers;
  std::vector<swarm::PeerRequest> requests;
  for (int i = 0; i < 16; ++i) {
    peers.push_back(std::make_unique<Peer>(100ms));
    requests.push_back(to("p" + std::to_string(i), peers.back()->port));
  }
  swarm::FanOut fan_out;
  const auto before = std::chrono::steady_clock::now();
  auto results = fan_out.run_and_wait(std::move(requests), 5000ms);
  const auto elapsed = std::chrono::steady_clock::now() - before;
  for (const auto& r : results) CHECK(r.status == 200);
  CHECK(elapsed < 1000ms);  // 16 × 100 ms one after another would be 1.6 s
}

TEST_CASE("hostnames resolve; the static ip is the fallback when the host does not resolve") {
  Peer a;
  swarm::FanOut fan_out;
  auto fallback = to("fallback", a.port, "no-such-robot.invalid");
  fallback.fallback_ip = "127.0.0.1";
  auto results = fan_out.run_and_wait({to("named", a.port, "localhost"), fallback, to("unresolvable", a.port, "no-such-robot.invalid")},
                                      2000ms);
  CHECK(results[0].status == 200);
  CHECK(results[1].status == 200);
  CHECK(results[1].address == "127.0.0.1:" + std::to_string(a.port));
  CHECK_FALSE(results[2].reachable);
  CHECK(results[2].error.find("cannot resolve host 'no-such-robot.invalid'") == 0);
  CHECK(results[2].error.find("no ip fallback") != std::string::npos);
}

TEST_CASE("an empty fan-out completes at once; stop() is idempotent") {
  swarm::FanOut fan_out;
  CHECK(fan_out.run_and_wait({}, 100ms).empty());
  fan_out.stop();
  fan_out.stop();
}

TEST_CASE("connections to a peer are kept and reused; one the peer closed while idle is replaced transparently") {
  http::ServerOptions options;
  options.address = "127.0.0.1";
  options.port = 0;
  options.idle_timeout = 200ms;  // the peer drops idle keep-alive connections quickly
  http::Server server(options, [](http::Request&&, http::Respond respond) { respond(http::Response{200, "application/json", "{}", {}}); });
  const auto port = server.start();
  swarm::FanOut fan_out;

  CHECK(fan_out.run_and_wait({to("p", port)}, 2000ms).at(0).status == 200);
  CHECK(server.connection_count() == 1);  // kept open for the next broadcast
  CHECK(fan_out.run_and_wait({to("p", port)}, 2000ms).at(0).status == 200);
  CHECK(server.connection_count() == 1);  // the same connection again

  // Wait (bounded) until the peer closed the idle connection, then send again: a fresh connection is made.
  const auto deadline = std::chrono::steady_clock::now() + 5s;
  while (server.connection_count() != 0 && std::chrono::steady_clock::now() < deadline) std::this_thread::sleep_for(10ms);
  REQUIRE(server.connection_count() == 0);
  auto again = fan_out.run_and_wait({to("p", port)}, 2000ms).at(0);
  CHECK(again.status == 200);
  CHECK(again.error.empty());
}


TEST_CASE("a stop answer over its body limit is that peer's failure; the others are not held back") {
  rcand::test::StreamingPeer streaming;
  Peer a;
  swarm::FanOut fan_out;
  auto big = to("streaming", streaming.port());
  big.body_limit = swarm::kStopAnswerLimit;
  auto results = fan_out.run_and_wait({big, to("a", a.port)}, 300ms);
  CHECK_FALSE(results[0].reachable);
  CAPTURE(results[0].error);
  CHECK(results[0].error.find("body limit") != std::string::npos);  // refused at the limit, not read until the deadline
  CHECK(results[1].status == 200);
}

TEST_CASE("100 concurrent broadcast stops with a streaming peer: each refuses the stream at its limit, none waits it out") {
  // Before issue 13 every run read the stream until its own 300 ms deadline on the one fan-out thread, and the
  // broadcasts answered 1.1-1.2 s late. Timing is measured by bench/broadcast_stop_streaming (README); here, what
  // makes it fast: the stream is refused at the limit, not timed out.
  rcand::test::StreamingPeer streaming;
  Peer a;
  swarm::FanOut fan_out;
  constexpr int kRuns = 100;
  std::mutex mutex;
  std::condition_variable all_done;
  std::vector<std::vector<swarm::PeerResult>> runs;
  const auto start = std::chrono::steady_clock::now();
  for (int i = 0; i < kRuns; ++i) {
    auto big = to("streaming", streaming.port());
    big.body_limit = swarm::kStopAnswerLimit;
    // A deadline far beyond the stop's: the assertion is about why each run ended, on any build (ASan -O0 too).
    fan_out.run({big, to("a", a.port)}, 10s, [&](std::vector<swarm::PeerResult> results) {
      std::lock_guard lock(mutex);
      runs.push_back(std::move(results));
      if (runs.size() == kRuns) all_done.notify_all();
    });
  }
  std::unique_lock lock(mutex);
  REQUIRE(all_done.wait_for(lock, 30s, [&] { return runs.size() == kRuns; }));
  MESSAGE("all " << kRuns << " concurrent broadcasts answered after "
                 << std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count() << " ms");
  for (const auto& results : runs) {
    REQUIRE(results.size() == 2);
    CAPTURE(results[0].error);
    CHECK(results[0].error.find("body limit") != std::string::npos);
    CHECK(results[1].status == 200);
  }
}

TEST_CASE("a run answers at its deadline while the fan-out thread is busy: the deadline is kept on a thread of its own") {
  // Issue 28 #3: one loop thread did every broadcast's I/O and kept their deadline timers, so under load (100
  // concurrent broadcast stops, hostile peers) the timers fired up to 225 ms late. Here one run's `done` holds the
  // fan-out thread for 800 ms, as a long queue of I/O would; a second run must still answer at its 300 ms deadline,
  // naming both of its peers as timed out (neither request could even be sent).
  Peer a;
  BlackHole silent;
  swarm::FanOut fan_out;
  std::promise<void> busy;
  fan_out.run({to("a", a.port)}, 5s, [&busy](std::vector<swarm::PeerResult>) {
    busy.set_value();
    std::this_thread::sleep_for(800ms);  // the fan-out thread is busy: this is what it simulates
  });
  busy.get_future().wait();
  const auto before = std::chrono::steady_clock::now();
  auto results = fan_out.run_and_wait({to("silent", silent.port()), to("a", a.port)}, 300ms);
  const auto elapsed = std::chrono::steady_clock::now() - before;
  CHECK(elapsed < 500ms);  // generous; before the fix it was the busy thread's 800 ms
  REQUIRE(results.size() == 2);
  for (const auto& r : results) {
    CHECK_FALSE(r.reachable);
    CHECK(r.error.find("timed out after 300 ms") != std::string::npos);
  }
  CHECK(results[0].name == "silent");
  CHECK(results[1].name == "a");
}

TEST_CASE("answer_by ends a run before its timeout: a broadcast stop's budget counts from its request") {
  BlackHole silent;
  Peer a;
  swarm::FanOut fan_out;
  std::promise<std::vector<swarm::PeerResult>> answered;
  const auto before = std::chrono::steady_clock::now();
  fan_out.run(
      {to("silent", silent.port()), to("a", a.port)}, 5s,
      [&answered](std::vector<swarm::PeerResult> results) { answered.set_value(std::move(results)); }, before + 200ms);
  auto results = answered.get_future().get();
  const auto elapsed = std::chrono::steady_clock::now() - before;
  CHECK(elapsed >= 199ms);
  CHECK(elapsed < 2s);  // far below the 5 s timeout
  CHECK(results[0].error.find("timed out after") != std::string::npos);
  CHECK(results[0].latency_ms < 1000.0);
  CHECK(results[1].status == 200);  // a fast peer is unaffected
}
