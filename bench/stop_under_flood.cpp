// POST /api/stop while the robot is attacked with connections (issue 13 #3): a real rcand on the bundled sim robot,
// the attacker and the operator both this process on loopback (one address: the per-address cap cannot tell them
// apart, so only the busy lane lets the stop in). Prints p50/p99/max of the stops (fresh connections, client clock).
//   flood: FLOOD connections (default 10,000), each sending an unauthenticated GET /api/status and kept open, opened
//          while stops are sent back to back, then 200 more stops with the whole flood open. Default limits.
//   loris: max_connections 1,000 (all allowed from one address), every slot held by a request that never ends (a
//          header line every round), and 100 more silent connections each round churning the busy lane; 200 stops.
//   bench_stop_under_flood [FLOOD]
#include <algorithm>
#include <atomic>
#include <cstdio>
#include <string>
#include <thread>
#include <vector>

#include "connection_flood.hpp"
#include "rcand_process.hpp"

using namespace rcand::test;

namespace {

double flood_percentile(std::vector<double> values, double p) {
  std::sort(values.begin(), values.end());
  return values[static_cast<std::size_t>(p * static_cast<double>(values.size() - 1))];
}

int report(const char* what, const std::vector<flood::TimedStop>& stops) {
  std::vector<double> ms;
  int failed = 0;
  for (const auto& stop : stops) {
    if (stop.status == 200 && stop.ms < 500.0) ms.push_back(stop.ms);
    else if (++failed == 1) std::printf("  first failure: status %d after %.1f ms %s\n", stop.status, stop.ms, stop.error.c_str());
  }
  if (ms.empty()) ms.push_back(0);
  std::printf("%s: %zu stops, %d not answered 200 within 500 ms; p50 %.2f ms, p99 %.2f ms, max %.2f ms\n", what,
              stops.size(), failed, flood_percentile(ms, 0.5), flood_percentile(ms, 0.99), flood_percentile(ms, 1.0));
  return failed;
}

int flood_run(std::size_t size) {
  RcandProcess rcand(sim_config());
  std::atomic<bool> flooding{true};
  std::vector<int> attack;
  attack.reserve(size);
  std::jthread attacker([&] {
    const std::string request = "GET /api/status HTTP/1.1\r\nHost: robot\r\n\r\n";
    for (std::size_t i = 0; i < size; ++i) {
      const int fd = flood::connect_to(rcand.port());
      if (fd < 0) break;
      attack.push_back(fd);
      if (i % 64 == 63)
        for (std::size_t j = i - 63; j <= i; ++j) flood::send_when_connected(attack[j], request);
    }
    flooding = false;
  });
  std::vector<flood::TimedStop> during, after;
  while (flooding.load()) during.push_back(flood::timed_stop(rcand));
  attacker.join();
  for (int i = 0; i < 200; ++i) after.push_back(flood::timed_stop(rcand));
  std::printf("flood of %zu connections (max_connections 10,000, 256 per address)\n", attack.size());
  const int failed = report("  stops while it opened", during) + report("  stops with it open", after);
  flood::close_all(attack);
  return failed;
}

int loris_run() {
  constexpr std::size_t kLimit = 1000;
  auto config = sim_config();
  config["runtime"]["max_connections"] = kLimit;
  config["runtime"]["max_connections_per_address"] = kLimit;
  RcandProcess rcand(config);
  std::vector<int> loris, silent;
  for (std::size_t i = 0; i < kLimit; ++i) {
    const int fd = flood::connect_to(rcand.port());
    if (fd < 0) break;
    flood::send_when_connected(fd, "GET /api/status HTTP/1.1\r\nHost: robot\r\n");
    loris.push_back(fd);
  }
  std::vector<flood::TimedStop> stops;
  std::size_t opened = 0;
  for (int round = 0; round < 200; ++round) {
    for (const int fd : loris) flood::send_now(fd, "X-Loris: 1\r\n");
    for (int i = 0; i < 100; ++i)
      if (const int fd = flood::connect_to(rcand.port()); fd >= 0) silent.push_back(fd);
    opened += 100;
    if (silent.size() > 2000) {  // long evicted by rcand: this process needs the descriptors back
      std::vector<int> oldest(silent.begin(), silent.begin() + 100);
      flood::close_all(oldest);
      silent.erase(silent.begin(), silent.begin() + 100);
    }
    stops.push_back(flood::timed_stop(rcand));
  }
  std::printf("slow-loris holding all %zu slots, %zu silent connections churning the busy lane\n", loris.size(), opened);
  const int failed = report("  stops", stops);
  flood::close_all(loris);
  flood::close_all(silent);
  return failed;
}

}  // namespace

int main(int argc, char** argv) {
  const std::size_t limit = flood::raise_open_files();
  std::size_t size = argc > 1 ? std::stoul(argv[1]) : 10'000;
  if (size + 1000 > limit) {
    size = limit > 1100 ? limit - 1000 : 100;
    std::printf("open-files limit %zu: the flood is %zu connections\n", limit, size);
  }
  const int failed = flood_run(size) + loris_run();
  return failed == 0 ? 0 : 1;
}
