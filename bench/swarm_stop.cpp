// Broadcast stop to a fleet of separate rcand processes on the sim drive: the time from sending
//   POST /api/stop + X-Swarm-Broadcast: true
// to one origin robot until (a) its answer, which carries every node's motor-stop confirmation, and (b) the last
// reachable node's drive reported both wheels at zero (zero_since_us on the sim drive's timeline; every process
// shares the machine's monotonic clock). Before each sample every robot is cleared and set moving.
//   bench_swarm_stop NODES [SAMPLES] [--unreachable]
// NODES is the size of the fleet: the origin plus NODES-1 peers; --unreachable adds one peer that accepts TCP and
// never answers (its per-node deadline bounds the broadcast).
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "libs/http/client.hpp"
#include "rcand_process.hpp"
#include "swarm_lab.hpp"

using namespace rcand::test;
using nlohmann::json;
namespace http = rcand::http;

namespace {

double percentile(std::vector<double> values, double p) {
  std::sort(values.begin(), values.end());
  return values[static_cast<std::size_t>(p * static_cast<double>(values.size() - 1))];
}

std::int64_t now_us() {
  return std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: bench_swarm_stop NODES [SAMPLES] [--unreachable]\n");
    return 2;
  }
  const int nodes = std::max(1, std::stoi(argv[1]));
  const int samples = argc > 2 && argv[2][0] != '-' ? std::stoi(argv[2]) : 100;
  bool unreachable = false;
  for (int i = 2; i < argc; ++i) unreachable = unreachable || std::string(argv[i]) == "--unreachable";

  std::vector<std::unique_ptr<RcandProcess>> robots;
  std::vector<SwarmEntry> entries;
  for (int i = 1; i < nodes; ++i) {
    robots.push_back(std::make_unique<RcandProcess>(swarm_robot_config("node" + std::to_string(i))));
    entries.push_back({"node" + std::to_string(i), "127.0.0.1", robots.back()->port()});
  }
  SilentPort silent;
  if (unreachable) entries.push_back({"unreachable", "127.0.0.1", silent.port()});
  TempDir dir;
  const auto swarm_file = dir.write("swarm.yaml", swarm_yaml(entries));
  robots.insert(robots.begin(), std::make_unique<RcandProcess>(swarm_robot_config("origin", swarm_file)));
  std::fprintf(stderr, "%zu rcand processes up%s\n", robots.size(), unreachable ? " plus one unreachable node" : "");

  const std::map<std::string, std::string> auth{{"Authorization", "Bearer owner-token"}};
  std::vector<http::Client> clients;
  for (const auto& robot : robots) clients.emplace_back("127.0.0.1", robot->port());
  const std::string move = R"({"type":"move","linear":0.4,"angular":0.0,"duration_ms":60000})";

  std::vector<double> answer_ms, last_zero_ms;
  for (int s = 0; s < samples; ++s) {
    for (auto& client : clients) {
      client.request("POST", "/api/estop/clear", "", auth);
      if (client.request("POST", "/api/action", move, auth).status != 200) {
        std::fprintf(stderr, "move refused\n");
        return 1;
      }
    }
    const auto start = now_us();
    auto headers = auth;
    headers["X-Swarm-Broadcast"] = "true";
    const auto answer = clients[0].request("POST", "/api/stop", "", headers);
    const auto answered = now_us();
    const auto report = json::parse(answer.body);
    const int expected_ok = nodes;
    if (answer.status != 200 || report["summary"]["ok"] != expected_ok) {
      std::fprintf(stderr, "broadcast stop answered %d: %s\n", answer.status, answer.body.c_str());
      return 1;
    }
    std::int64_t last_zero = 0;
    for (auto& client : clients) {
      const auto drive = json::parse(client.request("GET", "/api/drivers/drive0", "", auth).body)["status"];
      if (drive["moving"] != false) {
        std::fprintf(stderr, "a drive is still moving after the broadcast stop\n");
        return 1;
      }
      last_zero = std::max(last_zero, drive["zero_since_us"].get<std::int64_t>());
    }
    answer_ms.push_back(static_cast<double>(answered - start) / 1000.0);
    last_zero_ms.push_back(static_cast<double>(last_zero - start) / 1000.0);
  }
  std::printf("fleet %d nodes%s, %d samples\n", nodes, unreachable ? " + 1 unreachable" : "", samples);
  std::printf("  broadcast answer (every node confirmed) ms: p50 %.2f  p99 %.2f  max %.2f\n", percentile(answer_ms, 0.5),
              percentile(answer_ms, 0.99), percentile(answer_ms, 1.0));
  std::printf("  last reachable motor at zero ms:           p50 %.2f  p99 %.2f  max %.2f\n", percentile(last_zero_ms, 0.5),
              percentile(last_zero_ms, 0.99), percentile(last_zero_ms, 1.0));
  return 0;
}
