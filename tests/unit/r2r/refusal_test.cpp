// Issue 31 (N² chatter) and issue 28 #9 (20,000 anonymous MQTT messages gave 20,006 log lines): a message that came
// as a broadcast is never answered with an `error`, and one sender's refusals cost a bounded number of log lines and
// error answers, with a periodic summary of what was held back.
#include <doctest/doctest.h>

#include <spdlog/sinks/ostream_sink.h>

#include <sstream>

#include "libs/rcan/crypto.hpp"
#include "loopback_network.hpp"
#include "rcand/sdk/testing/manual_clock.hpp"
#include "services/r2r/r2r_node.hpp"
#include "services/r2r/refusal_throttle.hpp"

using namespace rcand;
using namespace rcand::kernel;
using namespace rcand::services::r2r;
using nlohmann::json;

namespace {

const std::string kRefusalToken = "refusal-test-token-0123456789ab";

// One robot, "bob", on a loopback network where "alice" and "flood" can be answered; its log captured.
struct RefusalRig {
  rcand::sdk::testing::ManualClock clock;
  r2r_test::LoopbackNetwork net;
  std::ostringstream log_text;
  std::unique_ptr<Authenticator> auth;
  std::unique_ptr<R2rNode> node;
  int commands = 0;

  RefusalRig() {
    net.endpoint("alice");
    net.endpoint("flood");
    AuthSettings settings;
    settings.tokens = {{"fleet", rcand::sdk::Role::User, sha256_hex(kRefusalToken)}};
    auth = std::make_unique<Authenticator>(settings);
    auto log = std::make_shared<spdlog::logger>("r2r-test", std::make_shared<spdlog::sinks::ostream_sink_mt>(log_text));
    log->set_pattern("%v");
    R2rNodeDeps deps{.identity = {"bob", "rcan://acme.rover.bob", {"nav"}},
                     .clock = clock,
                     .authenticator = *auth,
                     .settings = {},
                     .status_source = nullptr,
                     .command_executor =
                         [this](const Principal&, json, CommandDone done) {
                           ++commands;
                           done(423, {{"error", "e-stop is latched"}, {"code", "ESTOP_ACTIVE"}});
                         },
                     .transports = {&net.endpoint("bob")},
                     .fleet_member = nullptr,
                     .log = log,
                     .stop_executor = nullptr,
                     .after_stop = {}};
    node = std::make_unique<R2rNode>(std::move(deps));
    node->start();
  }

  // A message from `source` as it arrives over MQTT (no way back but the broker: answers go to r2r/<source>).
  void deliver(const std::string& source, const std::string& type, bool broadcast, bool with_token = false,
               const std::string& transport = "mqtt", const std::string& peer = "r2r/broadcast") {
    json header{{"version", "1.0"}, {"timestamp", clock.wall_ms() / 1000.0}, {"source_id", source}};
    if (with_token) header["auth"] = {{"token", kRefusalToken}};
    const json payload = type == "command" ? json{{"type", "move"}, {"linear", 0.1}} : json{{"battery", 50}};
    InboundMessage message;
    message.bytes = json{{"header", header}, {"type", type}, {"payload", payload}}.dump();
    message.transport = transport;
    message.peer = peer;
    message.broadcast = broadcast;
    node->receive(std::move(message));
  }

  int errors_sent() const {
    int errors = 0;
    for (const auto& sent : net.log) errors += sent.from == "bob" && sent.message["type"] == "error";
    return errors;
  }
  std::size_t log_lines(const std::string& needle) const {
    std::size_t count = 0;
    std::istringstream in(log_text.str());
    for (std::string line; std::getline(in, line);) count += line.find(needle) != std::string::npos;
    return count;
  }
};

}  // namespace

TEST_CASE("r2r refusals: a broadcast is never answered with an error; the same message sent to the robot is") {
  RefusalRig rig;
  rig.deliver("alice", "status", true);         // unauthenticated status broadcast
  rig.deliver("alice", "command", true, true);  // a broadcast command refused (423)
  InboundMessage broken{"{not json", "udp", "192.0.2.7:5000", std::nullopt, [](std::string) {}, true, true};
  rig.node->receive(std::move(broken));  // malformed, even with a route back
  CHECK(rig.commands == 1);
  CHECK(rig.errors_sent() == 0);
  CHECK(rig.node->counters().rejected == 2);

  rig.deliver("alice", "status", false, false, "mqtt", "r2r/bob");  // the same, sent to bob's own topic
  rig.deliver("alice", "command", false, true, "mqtt", "r2r/bob");
  CHECK(rig.errors_sent() == 2);
}

TEST_CASE("r2r refusals: 20,000 refused messages from one sender cost a few log lines and answers, then one summary") {
  RefusalRig rig;
  for (int i = 0; i < 20000; ++i) rig.deliver("flood", "command", false, false, "mqtt", "r2r/bob");
  CHECK(rig.node->counters().rejected == 20000);
  CHECK(rig.log_lines("unauthorized command from 'flood'") == static_cast<std::size_t>(RefusalThrottle::kLogBurst));
  CHECK(rig.errors_sent() == static_cast<int>(RefusalThrottle::kAnswerBurst));
  // Another sender still gets its own answer and line.
  rig.deliver("alice", "command", false, false, "mqtt", "r2r/bob");
  CHECK(rig.log_lines("unauthorized command from 'alice'") == 1);
  CHECK(rig.errors_sent() == static_cast<int>(RefusalThrottle::kAnswerBurst) + 1);

  rig.node->tick();  // too early for a summary
  CHECK(rig.log_lines("suppressed") == 0);
  rig.clock.advance(RefusalThrottle::kSummaryPeriod);
  rig.node->tick();
  CHECK(rig.log_lines("r2r: suppressed 19997 refusals from 'flood' (19997) in the last 10 s") == 1);
  CHECK(rig.log_lines("19990 error answers not sent") == 1);
  rig.node->tick();  // nothing new held back: no second summary
  CHECK(rig.log_lines("suppressed") == 1);
  // The sender's budgets refill: one more answer a second, one more line a minute.
  rig.deliver("flood", "command", false, false, "mqtt", "r2r/bob");
  CHECK(rig.errors_sent() == static_cast<int>(RefusalThrottle::kAnswerBurst) + 2);
  CHECK(rig.log_lines("unauthorized command from 'flood'") == static_cast<std::size_t>(RefusalThrottle::kLogBurst));
  rig.clock.advance(RefusalThrottle::kLogGap);
  rig.deliver("flood", "command", false, false, "mqtt", "r2r/bob");
  CHECK(rig.log_lines("unauthorized command from 'flood'") == static_cast<std::size_t>(RefusalThrottle::kLogBurst) + 1);
}

TEST_CASE("r2r refusals: new source_ids for every message gain nothing - per address, and for all senders together") {
  RefusalRig rig;
  // One UDP address, 5,000 names: the address's budget.
  for (int i = 0; i < 5000; ++i)
    rig.deliver("udp-" + std::to_string(i), "status", true, false, "udp", "192.0.2.7:" + std::to_string(1000 + i % 50));
  CHECK(rig.log_lines("unauthorized status from 'udp-") == static_cast<std::size_t>(RefusalThrottle::kLogBurst));
  CHECK(rig.errors_sent() == 0);  // UDP carries broadcasts only
  // MQTT hides the address: 20,000 names, each new, still within the budget for everyone.
  for (int i = 0; i < 20000; ++i) rig.deliver("mqtt-" + std::to_string(i), "command", false, false, "mqtt", "r2r/bob");
  CHECK(rig.log_lines("unauthorized command from 'mqtt-") <= static_cast<std::size_t>(RefusalThrottle::kTotalLogBurst));
  // (the answers go to r2r/<name>, where nobody listens on this test network: counted by the throttle alone)
  rig.clock.advance(RefusalThrottle::kSummaryPeriod);
  rig.node->tick();
  CHECK(rig.log_lines("other senders in the last 10 s") == 1);
}

TEST_CASE("r2r refusals: a name's budget is its own over each transport-level sender - nobody spends another's") {
  RefusalRig rig;
  const auto burst = static_cast<std::size_t>(RefusalThrottle::kLogBurst);
  // A UDP sender calling itself "alice" spends the budget of "alice" at its address, not that of alice over MQTT.
  for (int i = 0; i < 100; ++i) rig.deliver("alice", "status", true, false, "udp", "192.0.2.7:5000");
  CHECK(rig.log_lines("unauthorized status from 'alice'") == burst);
  rig.deliver("alice", "command", false, false, "mqtt", "r2r/bob");
  CHECK(rig.log_lines("unauthorized command from 'alice'") == 1);
  CHECK(rig.errors_sent() == 1);
  // Two WebSocket connections from one host (robots sharing a machine or a NAT): each connection has its budget.
  for (int i = 0; i < 100; ++i) rig.deliver("carol", "command", false, false, "ws", "127.0.0.1:40001");
  CHECK(rig.log_lines("unauthorized command from 'carol'") == burst);
  rig.deliver("dave", "command", false, false, "ws", "127.0.0.1:40002");
  CHECK(rig.log_lines("unauthorized command from 'dave'") == 1);
}
