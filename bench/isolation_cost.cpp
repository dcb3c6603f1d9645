// What process isolation costs per request (issue 34): the crasher fixture's capability (tests/plugins/crasher) on
// the sim robot, in rcand's process and then in its own (isolation: process), on one kept-alive connection each:
//   route   GET  /api/cap/org.rcand.test.crasher/pid    a capability route's round trip
//   motion  POST /api/cap/org.rcand.test.crasher/drive  a motion command through rcand's gate (the drive at half speed)
// and the resident memory of rcand and of the host process; then, with the capability in its own process, POST /api/stop
// (a clear between stops, on a connection of their own) on a quiet robot and while the capability's process is
// segfaulted four times and comes back after each (its backoff: 100, 200, 400, 800 ms). bench/run-isolation.sh
// builds and runs it.
//   bench_isolation_cost [SAMPLES]   (default 2000, after 200 not counted)
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include "libs/http/client.hpp"
#include "rcand_process.hpp"

namespace {

using Clock = std::chrono::steady_clock;
const std::string kBase = "/api/cap/org.rcand.test.crasher";

double percentile(std::vector<double> samples, double p) {
  std::sort(samples.begin(), samples.end());
  return samples[static_cast<std::size_t>(p * static_cast<double>(samples.size() - 1))];
}

// Microseconds per request, `samples` of them after the warm-up; exits when an answer is not 200.
std::vector<double> time_requests(rcand::http::Client& client, const char* method, const std::string& target, int samples) {
  std::vector<double> us;
  for (int i = -200; i < samples; ++i) {
    const auto start = Clock::now();
    const auto answer =
        client.request(method, target, std::string(method) == "POST" ? "{}" : "", {{"Authorization", "Bearer owner-token"}});
    const auto took = std::chrono::duration<double, std::micro>(Clock::now() - start).count();
    if (answer.status != 200) {
      std::fprintf(stderr, "%s %s answered %d: %s\n", method, target.c_str(), answer.status, answer.body.c_str());
      std::exit(1);
    }
    if (i >= 0) us.push_back(took);
  }
  return us;
}

// Stops (each followed by a clear) until `done` (or `count` of them when it is null); microseconds per stop.
std::vector<double> time_stops(rcand::http::Client& client, int count, const std::atomic<bool>* done) {
  std::vector<double> us;
  while (done != nullptr ? !done->load() : static_cast<int>(us.size()) < count) {
    const auto start = Clock::now();
    const auto stop = client.request("POST", "/api/stop", "", {{"Authorization", "Bearer guest-token"}});
    us.push_back(std::chrono::duration<double, std::micro>(Clock::now() - start).count());
    const auto clear = client.request("POST", "/api/estop/clear", "", {{"Authorization", "Bearer owner-token"}});
    if (stop.status != 200 || clear.status != 200) {
      std::fprintf(stderr, "stop %d, clear %d\n", stop.status, clear.status);
      std::exit(1);
    }
  }
  return us;
}

void print_stops(const char* what, const std::vector<double>& us) {
  std::printf("%-34s %6zu %12.1f %12.1f %12.1f\n", what, us.size(), percentile(us, 0.5), percentile(us, 0.99),
              *std::max_element(us.begin(), us.end()));
}

// The stop's figures while the isolated capability crashes and restarts, against the same robot quiet.
void stops_during_crashes(const rcand::test::RcandProcess& robot) {
  rcand::http::Client stops("127.0.0.1", robot.port()), crashes("127.0.0.1", robot.port());
  std::printf("\n%-34s %6s %12s %12s %12s\n", "POST /api/stop, capability isolated", "stops", "p50 us", "p99 us", "max us");
  time_stops(stops, 200, nullptr);  // warm-up
  print_stops("quiet", time_stops(stops, 2000, nullptr));
  std::atomic<bool> done{false};
  int deaths = 0;
  std::thread crasher([&] {
    const std::map<std::string, std::string> owner{{"Authorization", "Bearer owner-token"}};
    for (; deaths < 4; ++deaths) {
      while (crashes.request("GET", kBase + "/pid", "", owner).status != 200) {  // back in a new process
      }
      crashes.request("POST", kBase + "/crash", R"({"how":"segfault"})", owner);
    }
    while (crashes.request("GET", kBase + "/pid", "", owner).status != 200) {
    }
    done = true;
  });
  const auto during = time_stops(stops, 0, &done);
  crasher.join();
  print_stops(("during " + std::to_string(deaths) + " segfaults and restarts").c_str(), during);
}

}  // namespace

int main(int argc, char** argv) {
  const int samples = argc > 1 ? std::atoi(argv[1]) : 2000;
  std::printf("%d samples each, one kept-alive connection, after 200 not counted\n", samples);
  std::printf("%-11s %-7s %12s %12s %12s\n", "isolation", "request", "p50 us", "p99 us", "max us");
  for (const std::string isolation : {"in_process", "process"}) {
    auto config = rcand::test::sim_config();
    config["rcan_protocol"]["capabilities"].push_back("org.rcand.test.crasher");
    config["runtime"]["capabilities"]["org.rcand.test.crasher"] = {{"isolation", isolation}};
    rcand::test::RcandProcess robot(config, {rcand::test::plugin_dir(), rcand::test::test_plugin_dir() / "crasher"});
    rcand::http::Client client("127.0.0.1", robot.port());
    for (const auto& [name, method, target] :
         {std::tuple{"route", "GET", kBase + "/pid"}, std::tuple{"motion", "POST", kBase + "/drive"}}) {
      const auto us = time_requests(client, method, target, samples);
      std::printf("%-11s %-7s %12.1f %12.1f %12.1f\n", isolation.c_str(), name, percentile(us, 0.5), percentile(us, 0.99),
                  *std::max_element(us.begin(), us.end()));
    }
    const int host_pid = robot.json("GET", kBase + "/pid", "owner-token").value("pid", 0);
    std::printf("%-11s rss: rcand %ld kB", isolation.c_str(), rcand::test::resident_kb(robot.pid()));
    if (host_pid != robot.pid()) std::printf(", its host process %ld kB", rcand::test::resident_kb(host_pid));
    std::printf("\n");
    if (isolation == "process") stops_during_crashes(robot);
  }
  return 0;
}
