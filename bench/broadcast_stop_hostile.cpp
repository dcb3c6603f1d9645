// Concurrent broadcast stops to a hostile swarm (issue 28 #3): an origin rcand whose swarm is bravo (a real rcand)
// plus the nine misbehaving peers of tests/support/hostile_peers.hpp. Each round clears and moves both robots, then
// sends CONCURRENT POST /api/stop + X-Swarm-Broadcast at once, each on a fresh connection (one client thread).
// Prints, per round and overall: the client's time to each answer (p50/p99/max, how many over 500 ms), rcand's own
// per-node latency (the latest node's latency_ms in each report), how many reports had bravo stopped, and the origin's
// peak resident memory. Exit 1 when an answer is missing, malformed, or over 500 ms.
//   bench_broadcast_stop_hostile [CONCURRENT] [ROUNDS] [RAW_FILE]
// RAW_FILE (optional) gets one line per answer, "<client ms> <rcand's latest per-node ms>", for pooling runs.
// Run under load by bench/run-swarm-hostile.sh (it says how the machine is loaded).
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include "hostile_peers.hpp"
#include "rcand_process.hpp"
#include "swarm_lab.hpp"

using namespace rcand::test;
using nlohmann::json;

namespace {

double percentile(std::vector<double> values, double p) {
  if (values.empty()) return 0;
  std::sort(values.begin(), values.end());
  return values[static_cast<std::size_t>(p * static_cast<double>(values.size() - 1))];
}

// VmHWM of `pid` in KiB (0 when unreadable).
long peak_rss_kib(pid_t pid) {
  std::ifstream status("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(status, line))
    if (line.rfind("VmHWM:", 0) == 0) return std::stol(line.substr(6));
  return 0;
}

const std::string kMove = R"({"type":"move","linear":0.4,"angular":0.0,"duration_ms":60000})";

}  // namespace

int main(int argc, char** argv) {
  const int concurrent = argc > 1 ? std::max(1, std::stoi(argv[1])) : 100;
  const int rounds = argc > 2 ? std::max(1, std::stoi(argv[2])) : 12;
  std::ofstream raw;
  if (argc > 3) raw.open(argv[3], std::ios::app);
  HostilePeers hostile;
  RcandProcess bravo(swarm_robot_config("bravo"));
  auto entries = hostile.entries();
  entries.insert(entries.begin(), SwarmEntry{"bravo", "127.0.0.1", bravo.port()});
  TempDir dir;
  RcandProcess origin(swarm_robot_config("origin", dir.write("swarm.yaml", swarm_yaml(entries))));
  const std::size_t expected_nodes = entries.size() + 1;

  std::vector<double> all_ms, all_node_ms, all_read_ms;
  int over = 0, unexpected = 0, bravo_ok = 0;
  std::printf("broadcast stop to bravo + 9 hostile peers: %d concurrent x %d rounds\n", concurrent, rounds);
  for (int round = 0; round < rounds; ++round) {
    for (const RcandProcess* robot : {&origin, &bravo}) {
      robot->request("POST", "/api/estop/clear", "owner-token");
      if (robot->request("POST", "/api/action", "owner-token", kMove).status != 200) {
        std::fprintf(stderr, "move refused\n");
        return 1;
      }
    }
    const auto answers = concurrent_broadcast_stops(origin.port(), concurrent, std::chrono::milliseconds(5000));
    std::vector<double> round_ms, round_node_ms, round_read_ms;
    int round_over = 0;
    for (const auto& answer : answers) {
      round_ms.push_back(answer.ms);
      if (answer.ms >= 500.0) ++round_over;
      const auto report = json::parse(answer.body, nullptr, false);
      if (answer.status != 200 || !report.is_object() || report.value("nodes", json::array()).size() != expected_nodes ||
          report["motors_stopped"] != true) {
        ++unexpected;
        std::fprintf(stderr, "unexpected answer %d after %.1f ms (%s): %.300s\n", answer.status, answer.ms, answer.error.c_str(),
                     answer.body.c_str());
        continue;
      }
      double latest = 0;
      for (const auto& node : report["nodes"]) latest = std::max(latest, node.value("latency_ms", 0.0));
      round_node_ms.push_back(latest);
      // How long the request waited before rcand's stop handler read the clock (connect, accept, the queue of stops).
      round_read_ms.push_back(static_cast<double>(report.value("received_us", std::int64_t{0}) - answer.sent_us) / 1000.0);
      if (raw) raw << answer.ms << ' ' << latest << ' ' << round_read_ms.back() << '\n';
      if (node_named(report, "bravo")["ok"] == true) ++bravo_ok;
    }
    std::printf(
        "  round %2d: answer ms p50 %6.1f  p99 %6.1f  max %6.1f  over 500: %3d | per-node max %6.1f | read after max %6.1f\n",
        round + 1, percentile(round_ms, 0.5), percentile(round_ms, 0.99), percentile(round_ms, 1.0), round_over,
        percentile(round_node_ms, 1.0), percentile(round_read_ms, 1.0));
    over += round_over;
    all_ms.insert(all_ms.end(), round_ms.begin(), round_ms.end());
    all_node_ms.insert(all_node_ms.end(), round_node_ms.begin(), round_node_ms.end());
    all_read_ms.insert(all_read_ms.end(), round_read_ms.begin(), round_read_ms.end());
    std::this_thread::sleep_for(std::chrono::milliseconds(200));  // the peers' closes settle between rounds
  }
  std::printf("all %zu answers: ms p50 %.1f  p99 %.1f  p100 %.1f  over 500: %d  unexpected: %d  bravo ok: %d\n", all_ms.size(),
              percentile(all_ms, 0.5), percentile(all_ms, 0.99), percentile(all_ms, 1.0), over, unexpected, bravo_ok);
  std::printf("rcand's per-node latency (latest node of each report) ms: p50 %.1f  p99 %.1f  max %.1f\n",
              percentile(all_node_ms, 0.5), percentile(all_node_ms, 0.99), percentile(all_node_ms, 1.0));
  std::printf("stop handler reached after ms: p50 %.1f  p99 %.1f  max %.1f\n", percentile(all_read_ms, 0.5),
              percentile(all_read_ms, 0.99), percentile(all_read_ms, 1.0));
  std::printf("origin peak RSS: %.1f MiB\n", static_cast<double>(peak_rss_kib(origin.pid())) / 1024.0);
  return over == 0 && unexpected == 0 ? 0 : 1;
}
