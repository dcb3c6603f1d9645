// Broadcast stops while one swarm peer streams an endless answer (issue 13 #4): an origin rcand with two peers, a
// real rcand and a StreamingPeer; CONCURRENT clients each send POST /api/stop + X-Swarm-Broadcast at once, ROUNDS
// times. Prints p50/p99/max of the time to each answer; every answer must arrive within the 500 ms stop MUST.
//   bench_broadcast_stop_streaming [CONCURRENT] [ROUNDS]
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <future>
#include <string>
#include <vector>

#include "libs/http/client.hpp"
#include "rcand_process.hpp"
#include "streaming_peer.hpp"
#include "swarm_lab.hpp"

using namespace rcand::test;
using nlohmann::json;
namespace http = rcand::http;

namespace {

double percentile(std::vector<double> values, double p) {
  std::sort(values.begin(), values.end());
  return values[static_cast<std::size_t>(p * static_cast<double>(values.size() - 1))];
}

}  // namespace

int main(int argc, char** argv) {
  const int concurrent = argc > 1 ? std::max(1, std::stoi(argv[1])) : 100;
  const int rounds = argc > 2 ? std::max(1, std::stoi(argv[2])) : 10;
  StreamingPeer streaming;
  RcandProcess peer(swarm_robot_config("peer"));
  TempDir dir;
  const auto swarm_file =
      dir.write("swarm.yaml", swarm_yaml({{"peer", "127.0.0.1", peer.port()}, {"streaming", "127.0.0.1", streaming.port()}}));
  RcandProcess origin(swarm_robot_config("origin", swarm_file));
  const std::map<std::string, std::string> headers{{"Authorization", "Bearer guest-token"}, {"X-Swarm-Broadcast", "true"}};

  std::vector<double> answer_ms;
  int failures = 0;
  for (int round = 0; round < rounds; ++round) {
    std::vector<std::future<double>> stops;
    for (int i = 0; i < concurrent; ++i)
      stops.push_back(std::async(std::launch::async, [&] {
        http::Client client("127.0.0.1", origin.port(), std::chrono::milliseconds(5000));
        const auto start = std::chrono::steady_clock::now();
        http::ClientResponse answer;
        try {
          answer = client.request("POST", "/api/stop", "", headers);
        } catch (const http::ClientError&) {  // no answer within 5 s: a failure, counted below
        }
        const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
        const auto report = json::parse(answer.body, nullptr, false);
        const bool as_expected = answer.status == 200 && report.is_object() && report["summary"]["ok"] == 2 &&
                                 report["summary"]["failed"] == 1;  // origin and peer stopped; the streamer failed
        return as_expected ? ms : -ms;
      }));
    for (auto& stop : stops) {
      const double ms = stop.get();
      if (ms < 0) ++failures;
      answer_ms.push_back(ms < 0 ? -ms : ms);
    }
  }
  const double worst = percentile(answer_ms, 1.0);
  std::printf("broadcast stop with a streaming peer: %d concurrent x %d rounds\n", concurrent, rounds);
  std::printf("  answer ms: p50 %.1f  p99 %.1f  max %.1f  (limit 500)  unexpected reports: %d\n", percentile(answer_ms, 0.5),
              percentile(answer_ms, 0.99), worst, failures);
  return worst < 500.0 && failures == 0 ? 0 : 1;
}
