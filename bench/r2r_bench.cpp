// R2R benchmarks (issue 7) against real rcand processes on the sim drive:
//   bench_r2r transport [MESSAGES]   round trips through the whole node per transport:
//       ws   - a peer on WS /ws/r2r sends a direct task_request, the robot answers task_response on the connection;
//       mqtt - the same through a real mosquitto (r2r/<robot> in, r2r/<peer> out);
//       udp  - status datagrams between two UDP transports (one way, in process: UDP carries status only).
//     Latency = sequential round trips (p50/p99); throughput = MESSAGES sent back to back, until every answer arrived.
//   bench_r2r auction BIDDERS [ROUNDS]   a requester runs auctions among BIDDERS robots (WS, dialed from swarm.yaml):
//     the time from POST /api/r2r/auction to the decided answer, minus the bid window (target: under 50 ms).
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "mosquitto_broker.hpp"
#include "r2r_lab.hpp"
#include "rcand_process.hpp"
#include "services/r2r/transports/mqtt_transport.hpp"
#include "services/r2r/transports/udp_transport.hpp"
#include "ws_client.hpp"

using namespace rcand::test;
using namespace rcand::services::r2r;
using nlohmann::json;
using Clock = std::chrono::steady_clock;

namespace {

constexpr int kBidWindowMs = 1000;

double percentile(std::vector<double> values, double p) {
  if (values.empty()) return 0;
  std::sort(values.begin(), values.end());
  return values[static_cast<std::size_t>(p * static_cast<double>(values.size() - 1))];
}

double ms_since(Clock::time_point start) { return std::chrono::duration<double, std::milli>(Clock::now() - start).count(); }

std::string task_request(const std::string& source, int i, bool with_token) {
  json message = json::parse(r2r_message(source, "task_request",
                                         {{"task_id", "bench-" + std::to_string(i)}, {"required_capabilities", json::array()}},
                                         std::string("target")));
  if (with_token) message["header"]["auth"] = {{"token", "owner-token"}};
  return message.dump();
}

void report(const char* transport, const std::vector<double>& rtt, int messages, double burst_ms, const char* what) {
  std::printf("%-5s %-24s n=%zu p50=%.3f ms p99=%.3f ms max=%.3f ms | burst %d in %.1f ms = %.0f msg/s\n", transport, what,
              rtt.size(), percentile(rtt, 0.5), percentile(rtt, 0.99), percentile(rtt, 1.0), messages, burst_ms,
              messages / (burst_ms / 1000.0));
}

// Answers (task_response) collected from any thread.
struct Answers {
  std::mutex mutex;
  std::condition_variable changed;
  int count = 0;
  void add() {
    std::lock_guard lock(mutex);
    ++count;
    changed.notify_all();
  }
  bool wait(int target, std::chrono::milliseconds timeout = std::chrono::seconds(30)) {
    std::unique_lock lock(mutex);
    return changed.wait_for(lock, timeout, [&] { return count >= target; });
  }
};

int bench_ws(const RcandProcess& robot, int messages) {
  WsClient peer;
  if (peer.connect(robot.port(), "owner-token") != 101) return 1;
  auto next_response = [&]() {
    for (;;) {
      auto frame = peer.read(std::chrono::seconds(10));
      if (!frame) return false;
      if (frame->find("\"task_response\"") != std::string::npos) return true;
    }
  };
  std::vector<double> rtt;
  for (int i = 0; i < messages; ++i) {
    const std::string text = task_request("bench-peer", i, false);
    const auto start = Clock::now();
    peer.send(text);
    if (!next_response()) return 1;
    rtt.push_back(ms_since(start));
  }
  std::vector<std::string> burst;
  for (int i = 0; i < messages; ++i) burst.push_back(task_request("bench-peer", messages + i, false));
  const auto start = Clock::now();
  for (const auto& text : burst) peer.send(text);
  for (int i = 0; i < messages; ++i)
    if (!next_response()) return 1;
  report("ws", rtt, messages, ms_since(start), "task_request->response");
  return 0;
}

int bench_mqtt(std::uint16_t broker_port, int messages) {
  MqttOptions options;
  options.robot_name = "bench-peer";
  options.host = "127.0.0.1";
  options.port = broker_port;
  MqttTransport peer(options);
  Answers answers;
  peer.start([&](InboundMessage message) {
    if (message.bytes.find("\"task_response\"") != std::string::npos) answers.add();
  });
  // Until the robot answers, the subscriptions are not in place yet.
  for (int tries = 0; tries < 100; ++tries) {
    peer.send(task_request("bench-peer", -1 - tries, true), std::string("target"));
    if (answers.wait(1, std::chrono::milliseconds(100))) break;
  }
  if (!answers.wait(1)) return 1;
  std::this_thread::sleep_for(std::chrono::milliseconds(500));  // late answers to the warm-up land before we count
  std::vector<double> rtt;
  for (int i = 0; i < messages; ++i) {
    const int before = answers.count;
    const auto start = Clock::now();
    peer.send(task_request("bench-peer", i, true), std::string("target"));
    if (!answers.wait(before + 1)) return 1;
    rtt.push_back(ms_since(start));
  }
  const int before = answers.count;
  const auto start = Clock::now();
  for (int i = 0; i < messages; ++i) peer.send(task_request("bench-peer", messages + i, true), std::string("target"));
  if (!answers.wait(before + messages)) return 1;
  report("mqtt", rtt, messages, ms_since(start), "task_request->response");
  peer.stop();
  return 0;
}

int bench_udp(int messages) {
  UdpOptions receiver_options;
  receiver_options.bind_address = "127.0.0.1";
  UdpTransport receiver(receiver_options);
  Answers arrived;
  std::mutex mutex;
  std::vector<double> one_way;
  receiver.start([&](InboundMessage message) {
    const json status = json::parse(message.bytes, nullptr, false);
    const auto sent_ns = status["payload"]["sent_ns"].get<std::int64_t>();
    const auto now_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now().time_since_epoch()).count();
    {
      std::lock_guard lock(mutex);
      one_way.push_back(static_cast<double>(now_ns - sent_ns) / 1e6);
    }
    arrived.add();
  });
  UdpOptions sender_options;
  sender_options.bind_address = "127.0.0.1";
  sender_options.destinations = {{"127.0.0.1", receiver.bound_port()}};
  UdpTransport sender(sender_options);
  sender.start([](InboundMessage) {});
  auto status = [](int i) {
    const auto now_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now().time_since_epoch()).count();
    return json::parse(r2r_message("bench", "status", {{"battery", 50}, {"seq", i}, {"sent_ns", now_ns}})).dump();
  };
  for (int i = 0; i < messages; ++i) {
    sender.send(status(i), std::nullopt);
    if (!arrived.wait(i + 1, std::chrono::seconds(2))) return 1;  // sequential: one in flight
  }
  std::vector<double> latencies;
  {
    std::lock_guard lock(mutex);
    latencies = one_way;
  }
  const auto start = Clock::now();
  for (int i = 0; i < messages; ++i) sender.send(status(i), std::nullopt);
  arrived.wait(2 * messages, std::chrono::seconds(5));
  const double burst_ms = ms_since(start);
  std::printf(
      "udp   status one way             n=%zu p50=%.3f ms p99=%.3f ms max=%.3f ms | burst %d in %.1f ms = %.0f msg/s, "
      "%d of %d arrived\n",
      latencies.size(), percentile(latencies, 0.5), percentile(latencies, 0.99), percentile(latencies, 1.0), messages, burst_ms,
      messages / (burst_ms / 1000.0), arrived.count - messages, messages);
  return 0;
}

int bench_auction(int bidders, int rounds) {
  TempDir dir;
  const auto token = dir.write("r2r.token", "owner-token\n");
  std::vector<std::unique_ptr<RcandProcess>> fleet;
  std::vector<SwarmEntry> entries;
  for (int i = 0; i < bidders; ++i) {
    const std::string name = "bidder-" + std::to_string(i);
    fleet.push_back(std::make_unique<RcandProcess>(r2r_robot_config(name, token, 1.0 + i, 0.0)));
    entries.emplace_back(name, "127.0.0.1", fleet.back()->port());
  }
  const auto swarm_file = dir.write("swarm.yaml", swarm_yaml(entries));
  RcandProcess requester(r2r_robot_config("requester", token, 0, 0, swarm_file));
  std::vector<double> over;
  std::size_t bids = 0;
  for (int round = 0; round < rounds + 1; ++round) {  // the first one opens the connections: not counted
    int status = 0;
    const auto start = Clock::now();
    const auto result =
        requester.json("POST", "/api/r2r/auction", "owner-token",
                       json{{"required_capabilities", {"teleop"}}, {"location", {{"x", 0.0}, {"y", 0.0}}}}.dump(), &status);
    const double total = ms_since(start);
    if (status != 200 || result["state"] != "assigned") {
      std::fprintf(stderr, "auction failed: %d %s\n", status, result.dump().c_str());
      return 1;
    }
    if (round == 0) continue;
    over.push_back(total - kBidWindowMs);
    bids += result["bids"].size();
  }
  std::printf(
      "auction %2d bidders: %zu rounds, %.1f bids/round, decided after bid window + p50=%.1f ms p99=%.1f ms max=%.1f ms\n",
      bidders, over.size(), static_cast<double>(bids) / static_cast<double>(over.size()), percentile(over, 0.5),
      percentile(over, 0.99), percentile(over, 1.0));
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  const std::string mode = argc > 1 ? argv[1] : "";
  if (mode == "transport") {
    const int messages = argc > 2 ? std::max(10, std::stoi(argv[2])) : 2000;
    MosquittoBroker broker;
    TempDir dir;
    const auto token = dir.write("r2r.token", "owner-token\n");
    auto config = r2r_robot_config("target", token);
    config["runtime"]["logging"]["level"] = "warn";
    config["runtime"]["r2r"]["mqtt"] = {{"host", "127.0.0.1"}, {"port", broker.port()}};
    RcandProcess robot(config);
    // Direct requests are held by the bidder: a robot that holds thousands of tasks still answers each one.
    int rc = bench_ws(robot, messages);
    rc |= bench_mqtt(broker.port(), messages);
    rc |= bench_udp(messages);
    return rc;
  }
  if (mode == "auction") {
    const int bidders = argc > 2 ? std::max(1, std::stoi(argv[2])) : 3;
    const int rounds = argc > 3 ? std::max(1, std::stoi(argv[3])) : 10;
    return bench_auction(bidders, rounds);
  }
  std::fprintf(stderr, "usage: bench_r2r transport [MESSAGES] | bench_r2r auction BIDDERS [ROUNDS]\n");
  return 2;
}
