// Measures POST /api/stop on a running rcand: end-to-end latency (client clock) and the server's own halt latency
// (latency_us in the answer). Clears the e-stop between samples (with CLEAR_TOKEN, default TOKEN).
//   bench_stop_latency PORT TOKEN [SAMPLES] [keepalive|fresh] [CLEAR_TOKEN]
// keepalive (default): every stop on one kept-alive connection; fresh: each on a new connection, timed from
// connect() to the whole answer (an operator's panic button, or rcanctl stop).
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <string>
#include <vector>

#include "rcand/kernel/http/client.hpp"

namespace {
double percentile(std::vector<double> values, double p) {
  std::sort(values.begin(), values.end());
  const auto index = static_cast<std::size_t>(p * static_cast<double>(values.size() - 1));
  return values[index];
}
}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: bench_stop_latency PORT TOKEN [SAMPLES]\n");
    return 2;
  }
  const auto port = static_cast<std::uint16_t>(std::stoi(argv[1]));
  const std::map<std::string, std::string> auth{{"Authorization", std::string("Bearer ") + argv[2]}};
  const int samples = argc > 3 ? std::stoi(argv[3]) : 2000;
  const bool fresh = argc > 4 && std::string(argv[4]) == "fresh";
  const std::map<std::string, std::string> clear_auth{{"Authorization", std::string("Bearer ") + (argc > 5 ? argv[5] : argv[2])}};
  rcand::kernel::http::Client stop_client("127.0.0.1", port);
  rcand::kernel::http::Client clear_client("127.0.0.1", port);
  std::vector<double> end_to_end_us, server_us;
  for (int i = 0; i < samples; ++i) {
    const auto start = std::chrono::steady_clock::now();
    const auto answer = fresh ? rcand::kernel::http::request("127.0.0.1", port, "POST", "/api/stop", "", auth)
                              : stop_client.request("POST", "/api/stop", "", auth);
    const auto elapsed = std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - start).count();
    if (answer.status != 200) {
      std::fprintf(stderr, "stop answered %d: %s\n", answer.status, answer.body.c_str());
      return 1;
    }
    end_to_end_us.push_back(elapsed);
    server_us.push_back(nlohmann::json::parse(answer.body)["latency_us"].get<double>());
    clear_client.request("POST", "/api/estop/clear", "", clear_auth);
  }
  std::printf("samples %d, %s\n", samples, fresh ? "each stop on a fresh connection" : "one kept-alive connection");
  std::printf("stop end-to-end us: p50 %.0f  p99 %.0f  max %.0f\n", percentile(end_to_end_us, 0.5),
              percentile(end_to_end_us, 0.99), percentile(end_to_end_us, 1.0));
  std::printf("stop halt (server) us: p50 %.0f  p99 %.0f  max %.0f\n", percentile(server_us, 0.5), percentile(server_us, 0.99),
              percentile(server_us, 1.0));
  return 0;
}
