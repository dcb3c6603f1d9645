// Issue 13, findings 3 and 4: neither a connection flood nor a slow-loris at the limit locks out or delays the stop.
// A real rcand with small connection limits; the attacker is this process on loopback, from two other addresses
// (127.0.0.2 and .3, which together fill every slot) in the first flood, and from the operator's own in the second
// flood and the slow-loris.
// The 500 ms e-stop MUST is the one timed assertion; the figures are bench/stop_under_flood's.
#include <doctest/doctest.h>

#include <algorithm>
#include <atomic>
#include <string>
#include <thread>
#include <vector>

#include "connection_flood.hpp"
#include "rcand_process.hpp"
#include "sanitized_build.hpp"

using namespace rcand::test;
using nlohmann::json;

namespace {

constexpr std::size_t kFloodMaxConnections = 256;

nlohmann::json flood_config(std::size_t per_address) {
  auto config = sim_config();
  config["runtime"]["max_connections"] = kFloodMaxConnections;
  config["runtime"]["max_connections_per_address"] = per_address;
  return config;
}

// Every stop answered; within the 500 ms MUST (docs/protocol.md §6.5) unless `timed` is false (the sanitizer build runs rcand at
// -O0 many times slower: it checks the paths, the normal build their timing).
void check_stops(const std::vector<flood::TimedStop>& stops, bool timed = !kSanitizedBuild) {
  double worst = 0;
  for (const auto& stop : stops) {
    INFO(stop.error);
    CHECK(stop.status == 200);
    if (timed) CHECK(stop.ms < 500.0);
    worst = std::max(worst, stop.ms);
  }
  MESSAGE(stops.size() << " stops, slowest " << worst << " ms");
}

struct Flooded {
  std::vector<int> attack;  // the flood's sockets, still open
  std::vector<flood::TimedStop> stops;
};

// Opens `size` connections, the i-th from `source(i)` (nullptr: the operator's own address), each sending an
// unauthenticated status request and kept open - at once, or in batches of 64 once their handshakes are done - while
// stops are sent back to back; then 10 more stops with the whole flood open. A repeated stop halts again.
Flooded stop_through_flood(const RcandProcess& rcand, std::size_t size, const char* (*source)(std::size_t), bool batched) {
  const std::string request = "GET /api/status HTTP/1.1\r\nHost: robot\r\n\r\n";
  Flooded out;
  out.attack.reserve(size);
  std::atomic<bool> flooding{true};
  std::jthread attacker([&] {
    for (std::size_t i = 0; i < size; ++i) {
      const int fd = flood::connect_to(rcand.port(), source(i));
      if (fd < 0) break;
      out.attack.push_back(fd);
      if (!batched) flood::send_when_connected(fd, request);
      else if (i % 64 == 63)
        for (std::size_t j = i - 63; j <= i; ++j) flood::send_when_connected(out.attack[j], request);
    }
    flooding = false;
  });
  while (flooding.load()) out.stops.push_back(flood::timed_stop(rcand));
  attacker.join();
  for (int i = 0; i < 10; ++i) out.stops.push_back(flood::timed_stop(rcand));
  return out;
}

}  // namespace

TEST_CASE("a 10,000-connection flood from two other addresses: every stop is answered within 500 ms") {
  const std::size_t fd_limit = flood::raise_open_files();
  const std::size_t flood_size = std::min<std::size_t>(kSanitizedBuild ? 2'000 : 10'000, fd_limit > 600 ? fd_limit - 500 : 100);
  if (flood_size < 10'000 && !kSanitizedBuild)
    MESSAGE("the open-files limit " << fd_limit << " allows a flood of " << flood_size << " only");
  RcandProcess rcand(flood_config(128));
  Flooded flooded = stop_through_flood(
      rcand, flood_size, [](std::size_t i) { return i % 2 ? "127.0.0.2" : "127.0.0.3"; }, true);
  auto& attack = flooded.attack;  // references, not a structured binding: doctest's macros make lambdas (clang 14)
  const auto& stops = flooded.stops;
  MESSAGE(attack.size() << " flood connections");
  CHECK(attack.size() >= std::min<std::size_t>(flood_size, 1000));
  check_stops(stops);
  CHECK(rcand.json("GET", "/api/estop", "guest-token")["estopped"] == true);

  // Anything else beyond the limit is told to come back, not left hanging.
  const auto busy = rcand.request("GET", "/api/status", "guest-token");
  CHECK(busy.status == 503);
  CHECK(json::parse(busy.body)["code"] == "SERVER_BUSY");
  CHECK(busy.headers.count("retry-after") == 1);

  flood::close_all(attack);
  // Once the flood is gone the robot serves everyone again (the closes reach rcand asynchronously).
  int status = 0;
  for (int attempt = 0; attempt < 500 && status != 200; ++attempt)
    status = rcand.request("GET", "/api/status", "guest-token").status;
  CHECK(status == 200);
}

TEST_CASE("a flood of requests from the operator's own address: a stop from that address is never refused") {
  // Every flood connection sends a request at once, so a full busy lane holds waiters that have all sent something;
  // the lane gives up one of those (it would get 503 anyway) rather than refuse the stop (libs/http/busy_lane).
  const std::size_t fd_limit = flood::raise_open_files();
  const std::size_t flood_size = std::min<std::size_t>(kSanitizedBuild ? 1'000 : 4'000, fd_limit > 600 ? fd_limit - 500 : 100);
  RcandProcess rcand(flood_config(kFloodMaxConnections));  // one address may fill the server
  Flooded flooded = stop_through_flood(
      rcand, flood_size, [](std::size_t) -> const char* { return nullptr; }, false);
  auto& attack = flooded.attack;
  const auto& stops = flooded.stops;
  MESSAGE(attack.size() << " flood connections from the operator's address");
  check_stops(stops);
  flood::close_all(attack);
}

TEST_CASE("a slow-loris at the limit, with more silent connections churning the busy lane: every stop gets in") {
  flood::raise_open_files();
  RcandProcess rcand(flood_config(kFloodMaxConnections));  // one address may fill the server
  const std::uint16_t port = rcand.port();
  // Every slot held by a request that never ends: a header line now and then, never the blank line.
  std::vector<int> loris;
  for (std::size_t i = 0; i < kFloodMaxConnections; ++i) {
    const int fd = flood::connect_to(port);
    REQUIRE(fd >= 0);
    flood::send_when_connected(fd, "GET /api/status HTTP/1.1\r\nHost: robot\r\n");
    loris.push_back(fd);
  }
  std::vector<int> silent;
  std::vector<flood::TimedStop> stops;
  for (int round = 0; round < 20; ++round) {
    for (const int fd : loris) flood::send_now(fd, "X-Loris: 1\r\n");
    for (int i = 0; i < 100; ++i) {  // 100 more that send nothing, each round: more than the busy lane holds
      const int fd = flood::connect_to(port);
      if (fd >= 0) silent.push_back(fd);
    }
    stops.push_back(flood::timed_stop(rcand));
  }
  check_stops(stops);
  const auto busy = rcand.request("GET", "/api/status", "guest-token");
  CHECK(busy.status == 503);
  CHECK(busy.headers.count("retry-after") == 1);
  flood::close_all(loris);
  flood::close_all(silent);
}

TEST_CASE("a low open-files limit is named at startup, and connections are capped under it so a stop still gets in") {
  flood::raise_open_files();
  auto config = sim_config();
  config["runtime"]["max_connections_per_address"] = 10'000;
  RcandProcess rcand(config, {"/usr/bin/prlimit", "--nofile=600:600"}, "127.0.0.1");
  // 600 files, less the busy lane (256) and 256 for everything else: 88 connections.
  CHECK(rcand.stderr_text().find("the open-files limit is 600") != std::string::npos);
  CHECK(rcand.stderr_text().find("runtime.max_connections 10000 is served as 88") != std::string::npos);
  std::vector<int> held;
  for (int i = 0; i < 700; ++i) {  // more than rcand has descriptors for: without the cap accept() fails (EMFILE)
    const int fd = flood::connect_to(rcand.port());
    REQUIRE(fd >= 0);
    flood::send_when_connected(fd, "GET /health HTTP/1.1\r\nHost: robot\r\n\r\n");
    held.push_back(fd);
  }
  std::vector<flood::TimedStop> stops;
  for (int i = 0; i < 5; ++i) stops.push_back(flood::timed_stop(rcand));
  check_stops(stops, false);  // answered at all is the point (without the cap accept() fails): the flood tests time it
  flood::close_all(held);
}
