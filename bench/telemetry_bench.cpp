// The telemetry benchmark (issue 18): an rcand with the bundled sim robot and N WS /ws/telemetry clients (default 50)
// on one client thread, like a fleet of dashboards. Reported:
//  - frame-interval jitter: for every client, |gap between consecutive tick frames - 200 ms|, over the window
//    (default 30 s); p50, p99 and max across all clients. Measured where a client sees it (arrival on this machine's
//    steady clock), so it includes rcand's ticker, the fan-out, the sockets and this process's own wake-ups;
//  - e-stop push: T trials (default 30); each clears the latch, waits until every client saw the clear, then sends
//    POST /api/stop and times, per client, POST sent -> the frame with estopped=true read; the trial's figure is
//    the slowest client's ("pushed to all within"). p50, p99 and max over trials, and the HTTP answer's own time.
//   bench_telemetry [--clients N] [--seconds S] [--trials T]
#include <boost/asio/io_context.hpp>
#include <boost/beast/core/buffers_to_string.hpp>
#include <boost/beast/core/tcp_stream.hpp>
#include <boost/beast/websocket.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "rcand_process.hpp"

namespace {

namespace net = boost::asio;
namespace beast = boost::beast;
namespace websocket = boost::beast::websocket;
using nlohmann::json;
using Clock = std::chrono::steady_clock;

double percentile(std::vector<double> values, double p) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  return values[static_cast<std::size_t>(p * static_cast<double>(values.size() - 1))];
}

double ms(Clock::duration d) { return std::chrono::duration<double, std::milli>(d).count(); }

// One client: reads every frame, keeps tick arrival times and the first arrival of a latched / cleared state.
struct Client {
  explicit Client(net::io_context& io) : ws(io) {}
  websocket::stream<beast::tcp_stream> ws;
  beast::flat_buffer buffer;
  std::mutex mutex;  // below: written by the client thread, read by main
  std::vector<Clock::time_point> ticks;
  bool estopped = false;
  Clock::time_point changed_at;  // when `estopped` last changed as this client saw it
  std::atomic<bool> failed{false};

  void read() {
    ws.async_read(buffer, [this](beast::error_code ec, std::size_t) {
      const auto now = Clock::now();
      if (ec) {
        failed = true;
        return;
      }
      const json frame = json::parse(beast::buffers_to_string(buffer.data()), nullptr, false);
      buffer.consume(buffer.size());
      if (frame.is_object() && frame.value("type", "") == "telemetry") {
        std::lock_guard lock(mutex);
        if (frame.value("event", "") == "tick") ticks.push_back(now);
        const bool latched = frame.value("estopped", false);
        if (latched != estopped) {
          estopped = latched;
          changed_at = now;
        }
      }
      read();
    });
  }
};

int option(int argc, char** argv, const std::string& name, int fallback) {
  for (int i = 1; i + 1 < argc; ++i)
    if (argv[i] == name) return std::stoi(argv[i + 1]);
  return fallback;
}

}  // namespace

int main(int argc, char** argv) {
  const int clients_n = option(argc, argv, "--clients", 50);
  const int seconds = option(argc, argv, "--seconds", 30);
  const int trials = option(argc, argv, "--trials", 30);
  rcand::test::RcandProcess robot(rcand::test::sim_config());
  std::printf("rcand on port %u; %d telemetry clients\n", robot.port(), clients_n);

  net::io_context io;
  std::vector<std::unique_ptr<Client>> clients;
  for (int i = 0; i < clients_n; ++i) {
    auto client = std::make_unique<Client>(io);
    beast::get_lowest_layer(client->ws).connect(net::ip::tcp::endpoint(net::ip::make_address("127.0.0.1"), robot.port()));
    // As the OWNER: a principal below holds 8 sockets at most, 16 from one address (runtime.telemetry.*).
    client->ws.set_option(websocket::stream_base::decorator(
        [](websocket::request_type& request) { request.set(beast::http::field::authorization, "Bearer owner-token"); }));
    client->ws.handshake("127.0.0.1", "/ws/telemetry");
    client->read();
    clients.push_back(std::move(client));
  }
  auto guard = net::make_work_guard(io);
  std::thread runner([&io] { io.run(); });

  // Jitter window.
  std::this_thread::sleep_for(std::chrono::seconds(seconds));
  std::vector<double> jitter;
  std::size_t frames = 0;
  for (auto& client : clients) {
    std::lock_guard lock(client->mutex);
    frames += client->ticks.size();
    for (std::size_t i = 1; i < client->ticks.size(); ++i)
      jitter.push_back(std::abs(ms(client->ticks[i] - client->ticks[i - 1]) - 200.0));
  }
  std::printf("frame-interval jitter over %d s: %zu tick frames, %zu intervals: p50 %.3f ms  p99 %.3f ms  max %.3f ms\n", seconds,
              frames, jitter.size(), percentile(jitter, 0.5), percentile(jitter, 0.99), percentile(jitter, 1.0));

  // E-stop push trials.
  auto all_see = [&](bool latched, Clock::time_point after, Clock::time_point deadline, double& slowest_ms) {
    while (Clock::now() < deadline) {
      bool all = true;
      slowest_ms = 0;
      for (auto& client : clients) {
        std::lock_guard lock(client->mutex);
        if (client->estopped != latched || client->changed_at < after) {
          all = false;
          break;
        }
        if (after != Clock::time_point::min()) slowest_ms = std::max(slowest_ms, ms(client->changed_at - after));
      }
      if (all) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    return false;
  };
  std::vector<double> pushed_all, answered;
  for (int t = 0; t < trials; ++t) {
    robot.request("POST", "/api/estop/clear", "owner-token");
    double ignored = 0;
    if (!all_see(false, Clock::time_point::min(), Clock::now() + std::chrono::seconds(5), ignored)) {
      std::printf("trial %d: not every client saw the clear\n", t);
      continue;
    }
    // A random phase against the 200 ms tick, so trials do not all land at the same point of it.
    std::this_thread::sleep_for(std::chrono::milliseconds(50 + (t * 37) % 200));
    const auto sent = Clock::now();
    robot.request("POST", "/api/stop", "guest-token");
    answered.push_back(ms(Clock::now() - sent));
    double slowest = 0;
    if (!all_see(true, sent, sent + std::chrono::seconds(5), slowest)) {
      std::printf("trial %d: not every client saw the latch within 5 s\n", t);
      continue;
    }
    pushed_all.push_back(slowest);
  }
  std::printf(
      "e-stop pushed to all %d clients (POST sent -> last client read it), %zu trials: p50 %.3f ms  p99 %.3f ms  max %.3f ms\n",
      clients_n, pushed_all.size(), percentile(pushed_all, 0.5), percentile(pushed_all, 0.99), percentile(pushed_all, 1.0));
  std::printf("  POST /api/stop answered in: p50 %.3f ms  p99 %.3f ms\n", percentile(answered, 0.5), percentile(answered, 0.99));
  int failed = 0;
  for (auto& client : clients) failed += client->failed ? 1 : 0;
  std::printf("clients lost during the run: %d\n", failed);

  io.stop();
  runner.join();
  return failed == 0 && !jitter.empty() && static_cast<int>(pushed_all.size()) == trials ? 0 : 1;
}
