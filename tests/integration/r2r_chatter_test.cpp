// Issue 31 (N² chatter) and issue 28 #9 (forged log lines, refusal floods) against real rcand processes and a real
// mosquitto: robots without the fleet's signing keys never answer each other's status broadcasts with `error`; a
// flood of 20,000 unsigned messages from one sender costs a bounded number of log lines and error answers, summed
// up in one line; a source_id carrying a newline and a fake log line stays inside the line that quotes it.
#include <doctest/doctest.h>

#include <chrono>
#include <sstream>

#include "mosquitto_broker.hpp"
#include "mqtt_watch.hpp"
#include "r2r_lab.hpp"
#include "rcand_process.hpp"
#include "services/r2r/refusal_throttle.hpp"

using namespace rcand::test;
using nlohmann::json;
using namespace std::chrono_literals;
using rcand::services::r2r::RefusalThrottle;

namespace {

std::vector<std::string> chatter_lines(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

std::size_t chatter_lines_with(const std::string& text, const std::string& needle) {
  std::size_t count = 0;
  for (const auto& line : chatter_lines(text)) count += line.find(needle) != std::string::npos;
  return count;
}

}  // namespace

TEST_CASE("r2r chatter (mqtt): robots without signing keys never answer each other's status broadcasts with error") {
  MosquittoBroker broker;
  TempDir dir;
  const auto token = dir.write("r2r.token", "owner-token\n");
  MqttWatch watch(mqtt_client("watcher", broker.port(), {"r2r/#"}));  // every message on r2r/#
  REQUIRE(watch.connected());
  std::vector<std::unique_ptr<RcandProcess>> robots;
  for (const std::string name : {"alpha", "bravo", "charlie"}) {
    auto config = r2r_robot_config(name, token);  // a token, which MQTT never carries, and no signing keys
    // Each reads every robot's status (r2r/status/#), as a fleet view does: the case that used to cost N·(N-1) errors.
    config["runtime"]["r2r"]["mqtt"] = {
        {"host", "127.0.0.1"}, {"port", broker.port()}, {"keepalive_s", 5}, {"status_subscriptions", "all"}};
    robots.push_back(std::make_unique<RcandProcess>(config));
  }
  // Every robot has published its status (every 300 ms) several times, so each has refused the others' often.
  const auto heard = poll_until<bool>(
      [&]() -> std::optional<bool> {
        for (const std::string name : {"alpha", "bravo", "charlie"})
          if (watch.count(r2r_sent("status", name)) < 12) return std::nullopt;
        return true;
      },
      30s);
  REQUIRE(heard);
  const auto errors = watch.matching(r2r_type("error"));
  INFO("errors on the broker: " << (errors.empty() ? json() : errors.front()).dump());
  CHECK(errors.empty());  // was N·(N-1) a second: every status answered "authentication required"
  for (const auto& robot : robots) {
    const std::string log = robot->stderr_text();
    // Refused, and said so - a few times per sender, not once per status.
    const auto refusals = chatter_lines_with(log, "unauthorized status from '");
    CHECK(refusals >= 2);
    CHECK(refusals <= 2 * static_cast<std::size_t>(RefusalThrottle::kLogBurst));
    const auto counters = robot->json("GET", "/api/r2r/peers", "owner-token")["counters"];
    CHECK(counters["rejected"].get<int>() >= 6);
  }
}

TEST_CASE("r2r flood (mqtt): 20,000 unsigned messages from one sender, bounded lines and answers; forged lines stay quoted") {
  MosquittoBroker broker;
  TempDir dir;
  const auto token = dir.write("r2r.token", "owner-token\n");
  auto config = r2r_robot_config("alpha", token);
  config["runtime"]["r2r"]["mqtt"] = {{"host", "127.0.0.1"}, {"port", broker.port()}, {"keepalive_s", 5}};
  RcandProcess alpha(config);
  MqttWatch flood(mqtt_client("flood-watch", broker.port(), {"r2r/#"}));  // sees the answers to "flood" on r2r/flood
  REQUIRE(flood.connected());
  REQUIRE(poll_until<bool>([&]() -> std::optional<bool> {
    if (flood.count(r2r_sent("status", "alpha")) > 0) return true;  // alpha is on the broker
    return std::nullopt;
  }));
  auto received = [&] { return alpha.json("GET", "/api/r2r/peers", "owner-token")["counters"]["received"].get<long>(); };

  // Forged lines: a newline and a fake e-stop line, a journald priority, a terminal escape - in the source_id.
  const std::string forged = "x\nerror [kernel.estop] e-stop cleared by owner\n<3>rcand: forged critical\x1b[31m";
  REQUIRE(flood.transport().send(r2r_message(forged, "command", {{"type", "move"}}, std::string("alpha")), std::string("alpha")));
  REQUIRE(poll_until<bool>([&]() -> std::optional<bool> {
    if (alpha.stderr_text().find("e-stop cleared by owner") != std::string::npos) return true;
    return std::nullopt;
  }));
  for (const auto& line : chatter_lines(alpha.stderr_text())) {
    CHECK_FALSE(line.starts_with("error [kernel.estop]"));
    CHECK_FALSE(line.starts_with("<3>"));
    CHECK(line.find('\x1b') == std::string::npos);
  }
  CHECK(chatter_lines_with(alpha.stderr_text(),
                           "unauthorized command from 'x\\nerror [kernel.estop] e-stop cleared by owner\\n<3>rcand: forged "
                           "critical\\x1b[31m' via mqtt") == 1);

  // The flood, in batches the robot is let to catch up with (so the broker drops nothing for a slow subscriber).
  const long before = received();
  const auto started = std::chrono::steady_clock::now();
  constexpr int kFlood = 20000, kBatch = 1000;
  for (int sent = 0; sent < kFlood;) {
    for (int i = 0; i < kBatch; ++i, ++sent)
      REQUIRE(flood.transport().send(r2r_message("flood", "command", {{"type", "move"}, {"n", sent}}, std::string("alpha")),
                                     std::string("alpha")));
    REQUIRE(poll_until<bool>(
        [&]() -> std::optional<bool> {
          if (received() - before >= sent) return true;
          return std::nullopt;
        },
        30s));
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  // Every one refused, one summary line for what was not logged one by one.
  REQUIRE(poll_until<bool>(
      [&]() -> std::optional<bool> {
        if (alpha.stderr_text().find("refusals from 'flood'") != std::string::npos) return true;
        return std::nullopt;
      },
      30s));
  const std::string log = alpha.stderr_text();
  const auto flood_lines = chatter_lines_with(log, "from 'flood'");
  const auto r2r_lines = chatter_lines_with(log, "r2r:");
  const std::size_t answers = flood.count([](const std::string&, const json& m) {
    return wire_field(m, "/type") == "error" && wire_field(m, "/header/target_id") == "flood";
  });
  MESSAGE(kFlood << " messages in " << seconds << " s: " << flood_lines << " log lines about 'flood' (" << r2r_lines
                 << " r2r lines in all), " << answers << " error answers to it");
  // The first few, one a minute after them, and a summary every 10 s.
  CHECK(flood_lines <= static_cast<std::size_t>(RefusalThrottle::kLogBurst + seconds / 60 + seconds / 10) + 3);
  CHECK(r2r_lines < 60);  // was 20,006
  CHECK(answers >= 1);    // the sender is told why, at first
  CHECK(answers <= static_cast<std::size_t>(RefusalThrottle::kAnswerBurst + RefusalThrottle::kAnswersPerSecond * (seconds + 2)));
  CHECK(chatter_lines_with(log, "r2r: suppressed ") >= 1);
}
