// Soak: two sim robots (alpha, whose swarm file lists bravo, and bravo) under a paced mixed load - status polling,
// teleop moves, nav waypoints, stop/clear cycles and swarm broadcast stops - for --minutes N (default 10). Every
// interval (a minute; 5 s with --smoke, which runs 20 s) it prints per endpoint: requests, errors, p50/p99/max
// latency (client clock, kept-alive connections), and each robot's resident memory. Exit status 1 on any error.
//   bench_soak [--minutes N] [--smoke]
// An error is a transport failure or an answer the robot must not give: teleop refused with 423 or a nav waypoint
// with 409/423 while a stop is latched are correct answers, not errors.
#include <nlohmann/json.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <functional>
#include <map>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "libs/http/client.hpp"
#include "rcand_process.hpp"
#include "swarm_lab.hpp"

using namespace rcand::test;
using nlohmann::json;
namespace http = rcand::http;
using Clock = std::chrono::steady_clock;

namespace {

// Latencies and errors per endpoint, for the current interval and for the whole run.
class Ledger {
 public:
  void add(const std::string& endpoint, double micros, bool error, const std::string& why = {}) {
    std::lock_guard lock(mutex_);
    auto& now = interval_[endpoint];
    now.samples.push_back(micros);
    now.errors += error ? 1 : 0;
    auto& all = total_[endpoint];
    all.samples.push_back(micros);
    all.errors += error ? 1 : 0;
    if (error && first_errors_.size() < 20) first_errors_.push_back(endpoint + ": " + why);
  }
  // Prints and resets the interval; returns its error count.
  std::uint64_t print_interval(const std::string& title) {
    std::lock_guard lock(mutex_);
    std::printf("%s\n", title.c_str());
    const auto errors = print(interval_);
    interval_.clear();
    return errors;
  }
  std::uint64_t print_total() {
    std::lock_guard lock(mutex_);
    std::printf("== whole run ==\n");
    const auto errors = print(total_);
    for (const auto& error : first_errors_) std::printf("  error: %s\n", error.c_str());
    return errors;
  }

 private:
  struct Series {
    std::vector<double> samples;
    std::uint64_t errors = 0;
  };
  static double percentile(std::vector<double>& values, double p) {
    if (values.empty()) return 0;
    const auto index = static_cast<std::size_t>(p * static_cast<double>(values.size() - 1));
    std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(index), values.end());
    return values[index];
  }
  static std::uint64_t print(std::map<std::string, Series>& series) {
    std::uint64_t errors = 0;
    std::printf("  %-28s %9s %7s %9s %9s %9s\n", "endpoint", "requests", "errors", "p50_us", "p99_us", "max_us");
    for (auto& [name, s] : series) {
      const double max = s.samples.empty() ? 0 : *std::max_element(s.samples.begin(), s.samples.end());
      const double p50 = percentile(s.samples, 0.5), p99 = percentile(s.samples, 0.99);
      std::printf("  %-28s %9zu %7llu %9.0f %9.0f %9.0f\n", name.c_str(), s.samples.size(),
                  static_cast<unsigned long long>(s.errors), p50, p99, max);
      errors += s.errors;
    }
    return errors;
  }

  std::mutex mutex_;
  std::map<std::string, Series> interval_, total_;
  std::vector<std::string> first_errors_;
};

long rss_kb(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  for (std::string line; std::getline(in, line);)
    if (line.rfind("VmRSS:", 0) == 0) return std::stol(line.substr(6));
  return -1;
}

const std::map<std::string, std::string>& auth(const std::string& token) {
  static std::mutex mutex;
  static std::map<std::string, std::map<std::string, std::string>> headers;
  std::lock_guard lock(mutex);
  auto& entry = headers[token];
  if (entry.empty()) entry["Authorization"] = "Bearer " + token;
  return entry;
}

// One paced client: calls `step` every `period` on its own kept-alive connection until `stop`.
struct Pacer {
  std::thread thread;
  template <class Step> Pacer(std::atomic<bool>& stop, std::chrono::microseconds period, Step step) {
    thread = std::thread([&stop, period, step]() mutable {
      auto next = Clock::now();
      while (!stop.load()) {
        step();
        next += period;
        const auto now = Clock::now();
        if (next < now) next = now;  // behind: do not burst to catch up
        std::this_thread::sleep_until(next);
      }
    });
  }
};

// Times one request and files it; `ok` decides from the status and body whether the answer is a correct one.
void timed(Ledger& ledger, http::Client& client, const std::string& endpoint, const std::string& method,
           const std::string& target, const std::string& body, const std::map<std::string, std::string>& headers,
           const std::function<bool(int, const std::string&)>& ok) {
  const auto start = Clock::now();
  try {
    const auto answer = client.request(method, target, body, headers);
    const double micros = std::chrono::duration<double, std::micro>(Clock::now() - start).count();
    const bool good = ok(answer.status, answer.body);
    ledger.add(endpoint, micros, !good, good ? "" : std::to_string(answer.status) + " " + answer.body.substr(0, 200));
  } catch (const std::exception& e) {
    ledger.add(endpoint, std::chrono::duration<double, std::micro>(Clock::now() - start).count(), true, e.what());
  }
}

bool status_in(int status, std::initializer_list<int> allowed) {
  return std::find(allowed.begin(), allowed.end(), status) != allowed.end();
}

}  // namespace

int main(int argc, char** argv) {
  double minutes = 10;
  bool smoke = false;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--smoke") smoke = true;
    else if (arg == "--minutes" && i + 1 < argc) minutes = std::stod(argv[++i]);
    else {
      std::fprintf(stderr, "usage: bench_soak [--minutes N] [--smoke]\n");
      return 2;
    }
  }
  const auto duration = smoke ? std::chrono::seconds(20) : std::chrono::seconds(static_cast<long>(minutes * 60));
  const auto interval = smoke ? std::chrono::seconds(5) : std::chrono::seconds(60);

  auto robot_config = [](const std::string& name, const std::filesystem::path& swarm_file) {
    auto config = swarm_robot_config(name, swarm_file);
    config["rcan_protocol"]["capabilities"] = {"status", "teleop", "nav", "com.acme.gripper"};
    config["runtime"]["logging"]["level"] = "warn";  // the audit trail's info lines would dominate the soak's CPU
    return config;
  };
  TempDir dir;
  RcandProcess bravo(robot_config("bravo", {}));
  const auto swarm_file = dir.write("swarm.yaml", swarm_yaml({{"bravo", "127.0.0.1", bravo.port()}}));
  RcandProcess alpha(robot_config("alpha", swarm_file));
  std::printf("soak: %s, alpha pid %d port %u, bravo pid %d port %u, interval %llds\n", smoke ? "smoke (20 s)" : "full",
              alpha.pid(), alpha.port(), bravo.pid(), bravo.port(), static_cast<long long>(interval.count()));
  std::printf("rss_kb at start: alpha %ld bravo %ld\n", rss_kb(alpha.pid()), rss_kb(bravo.pid()));
  std::fflush(stdout);

  Ledger ledger;
  std::atomic<bool> stop{false};
  const auto alpha_port = alpha.port();
  auto client = [alpha_port] { return std::make_shared<http::Client>("127.0.0.1", alpha_port, std::chrono::seconds(5)); };
  const std::string move = R"({"type":"move","linear":0.2,"angular":0.1,"duration_ms":100})";
  std::vector<std::unique_ptr<Pacer>> pacers;
  using std::chrono::microseconds;

  for (int i = 0; i < 2; ++i) {  // status polling, 2 x 250/s
    pacers.push_back(std::make_unique<Pacer>(stop, microseconds(4000), [&ledger, c = client()] {
      timed(ledger, *c, "GET /api/status", "GET", "/api/status", "", auth("guest-token"),
            [](int s, const std::string&) { return s == 200; });
    }));
  }
  pacers.push_back(std::make_unique<Pacer>(stop, microseconds(6667), [&ledger, c = client(), move] {  // teleop 150/s
    timed(ledger, *c, "POST /api/action move", "POST", "/api/action", move, auth("user-token"),
          [](int s, const std::string&) { return status_in(s, {200, 423}); });
  }));
  pacers.push_back(std::make_unique<Pacer>(stop, microseconds(200000), [&ledger, c = client()] {  // nav 5/s
    timed(ledger, *c, "POST /api/nav/waypoint", "POST", "/api/nav/waypoint", R"({"distance_m":0.02,"heading_deg":5,"speed":1})",
          auth("user-token"), [](int s, const std::string&) { return status_in(s, {200, 409, 423}); });
    timed(ledger, *c, "GET /api/nav/status", "GET", "/api/nav/status", "", auth("guest-token"),
          [](int s, const std::string&) { return s == 200; });
  }));
  pacers.push_back(std::make_unique<Pacer>(stop, microseconds(50000), [&ledger, c = client()] {  // stop + clear, 20/s
    timed(ledger, *c, "POST /api/stop", "POST", "/api/stop", "", auth("guest-token"), [](int s, const std::string& body) {
      return s == 200 && json::parse(body, nullptr, false).value("motors_stopped", false);
    });
    timed(ledger, *c, "POST /api/estop/clear", "POST", "/api/estop/clear", "", auth("owner-token"),
          [](int s, const std::string&) { return s == 200; });
  }));
  const auto bravo_port = bravo.port();
  pacers.push_back(std::make_unique<Pacer>(stop, microseconds(2000000), [&ledger, c = client(), bravo_port] {  // swarm
    std::map<std::string, std::string> headers = auth("guest-token");
    headers["X-Swarm-Broadcast"] = "true";
    timed(ledger, *c, "POST /api/stop (broadcast)", "POST", "/api/stop", "", headers, [](int s, const std::string& body) {
      const auto report = json::parse(body, nullptr, false);
      return s == 200 && report.is_object() && report["summary"].value("failed", 1) == 0 &&
             report["summary"].value("total", 0) == 2;
    });
    http::Client bravo_client("127.0.0.1", bravo_port, std::chrono::seconds(5));
    timed(ledger, bravo_client, "POST /api/estop/clear (peer)", "POST", "/api/estop/clear", "", auth("owner-token"),
          [](int s, const std::string&) { return s == 200; });
    timed(ledger, *c, "POST /api/estop/clear", "POST", "/api/estop/clear", "", auth("owner-token"),
          [](int s, const std::string&) { return s == 200; });
  }));

  const auto start = Clock::now();
  std::uint64_t errors = 0;
  long alpha_after_first = -1, bravo_after_first = -1, alpha_peak = 0, bravo_peak = 0;
  for (int n = 1; Clock::now() - start < duration; ++n) {
    std::this_thread::sleep_until(start + interval * n);
    const long a = rss_kb(alpha.pid()), b = rss_kb(bravo.pid());
    char title[200];
    std::snprintf(title, sizeof title, "== interval %d (t=%llds) rss_kb alpha %ld bravo %ld ==", n,
                  static_cast<long long>(std::chrono::duration_cast<std::chrono::seconds>(interval * n).count()), a, b);
    errors += ledger.print_interval(title);
    std::fflush(stdout);
    if (n == 1) alpha_after_first = a, bravo_after_first = b;
    alpha_peak = std::max(alpha_peak, a), bravo_peak = std::max(bravo_peak, b);
  }
  stop = true;
  for (auto& pacer : pacers) pacer->thread.join();
  errors = ledger.print_total();
  std::printf("memory growth after the first interval: alpha %+ld kB (peak %ld), bravo %+ld kB (peak %ld)\n",
              alpha_peak - alpha_after_first, alpha_peak, bravo_peak - bravo_after_first, bravo_peak);
  const auto audit = alpha.json("GET", "/api/audit?limit=1", "owner-token");
  std::printf("alpha audit: total %s, dropped from memory %s (bounded ring of 10000; runtime.audit_file keeps all)\n",
              audit.value("total", json()).dump().c_str(), audit.value("dropped", json()).dump().c_str());
  std::printf("errors: %llu\n", static_cast<unsigned long long>(errors));
  return errors == 0 ? 0 : 1;
}
