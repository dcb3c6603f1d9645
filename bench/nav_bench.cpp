// Measures nav on a running rcand with the sim drive, from the drive's motor timeline (kernel steady clock):
//  1. POST /api/stop received -> motors at zero, while a nav job runs (mid-turn or mid-drive, alternating);
//     "received" is the received_us the stop answer carries, "zero" the first zero event in the timeline after it.
//  2. commanded vs actual phase durations: a 200 ms turn then a 200 ms drive per job, actual = timeline spacing.
//   bench_nav PORT TOKEN [SAMPLES]
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <thread>
#include <vector>

#include "libs/http/client.hpp"

namespace {

using nlohmann::json;

double percentile(std::vector<double> values, double p) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  return values[static_cast<std::size_t>(p * static_cast<double>(values.size() - 1))];
}

void report(const char* what, const std::vector<double>& v) {
  std::printf("%-44s p50 %8.1f  p99 %8.1f  max %8.1f  (n=%zu)\n", what, percentile(v, 0.5), percentile(v, 0.99),
              percentile(v, 1.0), v.size());
}

struct Bench {
  rcand::http::Client client;
  std::map<std::string, std::string> auth;

  json call(const std::string& method, const std::string& target, const std::string& body = {}) {
    const auto answer = client.request(method, target, body, auth);
    if (answer.status >= 300) {
      std::fprintf(stderr, "%s %s answered %d: %s\n", method.c_str(), target.c_str(), answer.status, answer.body.c_str());
      std::exit(1);
    }
    return json::parse(answer.body);
  }
  json timeline() { return call("GET", "/api/drivers/drive0")["status"]["timeline"]; }
  void wait_idle() {
    while (call("GET", "/api/nav/status")["running"] == true) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
};

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: bench_nav PORT TOKEN [SAMPLES]\n");
    return 2;
  }
  const auto port = static_cast<std::uint16_t>(std::stoi(argv[1]));
  const int samples = argc > 3 ? std::stoi(argv[3]) : 200;
  Bench bench{rcand::http::Client("127.0.0.1", port), {{"Authorization", std::string("Bearer ") + argv[2]}}};

  // 1. Stop latency during a running job. Turn 90 deg at 0.5 (1.44 s) then drive: stopping 20-60 ms in lands
  //    mid-turn; waiting for "driving" first lands mid-drive.
  std::vector<double> stop_to_zero_us, stop_round_trip_us;
  for (int i = 0; i < samples; ++i) {
    bench.call("POST", "/api/estop/clear");
    bench.wait_idle();
    bench.call("POST", "/api/nav/waypoint", R"({"distance_m":0.5,"heading_deg":10,"speed":0.5})");
    if (i % 2 == 1)
      while (bench.call("GET", "/api/nav/status")["state"] != "driving") std::this_thread::sleep_for(std::chrono::milliseconds(2));
    std::this_thread::sleep_for(std::chrono::milliseconds(20 + (i * 7) % 40));
    const auto start = std::chrono::steady_clock::now();
    const json stopped = bench.call("POST", "/api/stop");
    stop_round_trip_us.push_back(std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - start).count());
    const auto received = stopped["received_us"].get<std::int64_t>();
    for (const auto& e : bench.timeline()) {
      if (e["t_us"].get<std::int64_t>() >= received && e["left"] == 0.0 && e["right"] == 0.0) {
        stop_to_zero_us.push_back(static_cast<double>(e["t_us"].get<std::int64_t>() - received));
        break;
      }
    }
  }
  bench.call("POST", "/api/estop/clear");
  bench.wait_idle();

  // 2. Phase timing: turn 25 deg at speed 1 (200 ms), then drive 0.042 m at speed 1 (200 ms).
  std::vector<double> turn_error_us, drive_error_us;
  for (int i = 0; i < samples; ++i) {
    const json started = bench.call("POST", "/api/nav/waypoint", R"({"distance_m":0.042,"heading_deg":25,"speed":1.0})");
    const auto from = started["started_us"].get<std::int64_t>() - 1000;
    bench.wait_idle();
    std::vector<json> events;
    for (const auto& e : bench.timeline())
      if (e["t_us"].get<std::int64_t>() >= from) events.push_back(e);
    if (events.size() < 3) continue;
    const double t0 = events[0]["t_us"].get<double>(), t1 = events[1]["t_us"].get<double>(), t2 = events[2]["t_us"].get<double>();
    turn_error_us.push_back(std::abs((t1 - t0) - 200'000.0));
    drive_error_us.push_back(std::abs((t2 - t1) - 200'000.0));
  }

  std::printf("samples %d\n", samples);
  report("stop received -> motors at zero (us)", stop_to_zero_us);
  report("POST /api/stop round trip, client (us)", stop_round_trip_us);
  report("|actual - commanded| turn, 200 ms (us)", turn_error_us);
  report("|actual - commanded| drive, 200 ms (us)", drive_error_us);
  return 0;
}
