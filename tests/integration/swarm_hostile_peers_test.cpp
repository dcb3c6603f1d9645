// Issue 28 #3: concurrent broadcast stops to a swarm of one real robot (bravo) and the nine hostile peers of
// tests/support/hostile_peers.hpp. Every answer must come within the 500 ms stop MUST (docs/protocol.md §14.5.2),
// name every node, report bravo stopped (a hostile node delays nobody) and each hostile node as that node's failure.
// Timing under heavy load is measured by bench/run-swarm-hostile.sh (README); here fewer stops, the MUST itself.
#include <doctest/doctest.h>

#include <chrono>

#include "eventually.hpp"
#include "hostile_peers.hpp"
#include "rcand_process.hpp"
#include "sanitized_build.hpp"
#include "swarm_lab.hpp"

using namespace rcand::test;
using nlohmann::json;

namespace {

bool error_mentions(const json& node, const std::string& words) {
  return node["error"].is_string() && node["error"].get<std::string>().find(words) != std::string::npos;
}

}  // namespace

TEST_CASE("swarm: concurrent broadcast stops to bravo and nine hostile peers each answer within 500 ms; bravo stops") {
  constexpr int kConcurrent = 20;
  HostilePeers hostile;
  RcandProcess bravo(swarm_robot_config("bravo"));
  auto entries = hostile.entries();
  entries.insert(entries.begin(), SwarmEntry{"bravo", "127.0.0.1", bravo.port()});
  TempDir dir;
  RcandProcess origin(swarm_robot_config("origin", dir.write("swarm.yaml", swarm_yaml(entries))));
  for (const RcandProcess* robot : {&origin, &bravo}) {
    int status = 0;
    robot->json("POST", "/api/action", "user-token", R"({"type":"move","linear":0.5,"angular":0.0,"duration_ms":5000})", &status);
    REQUIRE(status == 200);
  }

  const auto answers = concurrent_broadcast_stops(origin.port(), kConcurrent, std::chrono::milliseconds(5000));
  for (const auto& answer : answers) {
    INFO(answer.error << " " << answer.body.substr(0, 2000));
    REQUIRE(answer.status == 200);
    if (!kSanitizedBuild) CHECK(answer.ms < 500.0);  // §14.5.2 MUST, whatever the peers do
    const auto report = json::parse(answer.body);
    CHECK(report["motors_stopped"] == true);
    REQUIRE(report["nodes"].size() == entries.size() + 1);
    // ASan slows every process 2-5x: on a loaded machine a peer's answer can miss the fan-out's 300 ms, which the
    // report must then say ("timed out"). The normal build asserts the exact outcome of each peer.
    const auto kind = [](const json& node, const char* expected) {
      return error_mentions(node, expected) || (kSanitizedBuild && error_mentions(node, "timed out"));
    };
    CHECK(node_named(report, "origin")["ok"] == true);
    const auto b = node_named(report, "bravo");
    if (kSanitizedBuild && !b.value("ok", false)) {
      CHECK(error_mentions(b, "timed out"));
    } else {
      CHECK(report["summary"] == json{{"total", 11}, {"ok", 2}, {"failed", 9}});
      CHECK(b.value("ok", false));
      CHECK(b.value("motors_stopped", false));
    }
    for (const auto& name : HostilePeers::names()) {
      const auto node = node_named(report, name);
      CAPTURE(node.dump());
      CHECK(node["ok"] == false);
      CHECK(node["executed"] == false);
    }
    // What each misbehaviour is reported as: the limits refuse what never ends, the deadline ends what never comes.
    for (const char* name : {"sleeper", "byte_by_byte", "backlog"}) CHECK(error_mentions(node_named(report, name), "timed out"));
    CHECK(kind(node_named(report, "headers"), "header limit"));
    CHECK(kind(node_named(report, "chunked"), "body limit"));
    CHECK(kind(node_named(report, "mistyped"), "body limit"));
    CHECK(error_mentions(node_named(report, "refused"), "cannot connect"));
  }
  for (const RcandProcess* robot : {&origin, &bravo}) {  // a stop that answered late still latched (sanitized builds)
    CHECK(eventually([robot] { return robot->json("GET", "/api/estop", "guest-token")["estopped"] == true; },
                     std::chrono::seconds(10), std::chrono::milliseconds(50)));
    CHECK(drive_status(*robot)["moving"] == false);
  }
}
