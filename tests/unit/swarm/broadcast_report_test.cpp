// The per-node entries of docs/protocol.md §9 from peers' answers.
#include <doctest/doctest.h>

#include "libs/swarm/broadcast_report.hpp"

using namespace rcand::swarm;
using nlohmann::json;

namespace {

PeerResult answered(int status, json body) {
  PeerResult r;
  r.name = "n";
  r.address = "127.0.0.1:1";
  r.reachable = true;
  r.status = status;
  r.body = body.dump();
  r.latency_ms = 1.5;
  return r;
}

}  // namespace

TEST_CASE("a stop confirmed by the node is ok and executed") {
  auto entry = node_entry(answered(200, {{"status", "stopped"}, {"motors_stopped", true}}), BroadcastKind::Stop);
  CHECK(entry["ok"] == true);
  CHECK(entry["executed"] == true);
  CHECK(entry["motors_stopped"] == true);
  CHECK(entry["http_status"] == 200);
  CHECK(entry["error"].is_null());
  CHECK(entry["latency_ms"] == 1.5);
  auto unconfirmed = node_entry(answered(200, {{"motors_stopped", false}}), BroadcastKind::Stop);
  CHECK(unconfirmed["ok"] == false);
  CHECK(unconfirmed["error"].is_string());
}

TEST_CASE("the e-stop acknowledgement is ok but not executed") {
  auto entry = node_entry(answered(200, {{"ack", true}, {"executed", false}, {"reason", "estop_active"}}), BroadcastKind::Command);
  CHECK(entry["ok"] == true);
  CHECK(entry["executed"] == false);
  CHECK(entry["reason"] == "estop_active");
}

TEST_CASE("refusals and transport failures are failures with a reason") {
  auto missing = node_entry(answered(404, {{"error", "no chat"}, {"code", "CAPABILITY_NOT_FOUND"}, {"status", 404}}),
                            BroadcastKind::Command);
  CHECK(missing["ok"] == false);
  CHECK(missing["executed"] == false);
  CHECK(missing["http_status"] == 404);
  CHECK(missing["code"] == "CAPABILITY_NOT_FOUND");
  CHECK(missing["error"] == "no chat");
  PeerResult dead;
  dead.name = "dead";
  dead.error = "cannot connect to 127.0.0.1:1: Connection refused";
  auto entry = node_entry(dead, BroadcastKind::Stop);
  CHECK(entry["ok"] == false);
  CHECK(entry["http_status"].is_null());
  CHECK(entry["error"] == dead.error);
  auto ok = node_entry(answered(200, {{"raw_text", "hi"}}), BroadcastKind::Command);
  CHECK(ok["ok"] == true);
  CHECK(ok["executed"] == true);
  CHECK(ok["response"]["raw_text"] == "hi");
}

TEST_CASE("the document counts ok and failed nodes") {
  auto doc = broadcast_document({json{{"name", "a"}, {"ok", true}}, json{{"name", "b"}, {"ok", false}}, json{{"name", "c"}, {"ok", true}}});
  CHECK(doc["broadcast"] == true);
  CHECK(doc["nodes"].size() == 3);
  CHECK(doc["summary"] == json{{"total", 3}, {"ok", 2}, {"failed", 1}});
}

TEST_CASE("a lying peer is that node's failure, never an exception: every field it sends is type-checked") {
  // Issue 13 #1: "motors_stopped":"yes" aborted the broadcasting rcand (json type_error on the fan-out thread).
  const std::vector<std::pair<json, BroadcastKind>> lies = {
      {{{"motors_stopped", "yes"}}, BroadcastKind::Stop},
      {{{"motors_stopped", 1}}, BroadcastKind::Stop},
      {{{"motors_stopped", nullptr}}, BroadcastKind::Stop},
      {{{"ack", "yes"}, {"executed", false}}, BroadcastKind::Command},
      {{{"ack", true}, {"executed", "no"}}, BroadcastKind::Command},
      {{{"executed", json::array()}}, BroadcastKind::Command},
      {{{"ack", json::object()}}, BroadcastKind::Stop},
  };
  for (const auto& lie : lies) {
    const auto& body = lie.first;
    const auto kind = lie.second;
    CAPTURE(body.dump());
    json entry;
    CHECK_NOTHROW(entry = node_entry(answered(200, body), kind));
    CHECK(entry["ok"] == false);
    CHECK(entry["executed"] == false);
    CHECK(entry["code"] == "MALFORMED_ANSWER");
    CHECK(entry["error"].get<std::string>().find("malformed answer") != std::string::npos);
  }
  // Text fields of the wrong type are dropped, and long ones are bounded, in failures too.
  auto refusal = node_entry(answered(500, {{"error", 42}, {"code", json::array()}}), BroadcastKind::Stop);
  CHECK(refusal["error"] == "HTTP 500");
  auto flood = node_entry(answered(503, {{"error", std::string(100000, 'x')}, {"code", "UNAVAILABLE"}}), BroadcastKind::Stop);
  CHECK(flood["error"].get<std::string>().size() <= 200);
  // A document whose "ok" is not a boolean counts the node as failed.
  CHECK(broadcast_document({json{{"name", "x"}, {"ok", "yes"}}})["summary"]["failed"] == 1);
}

TEST_CASE("a large answer is summarised, not copied into the report") {
  json big{{"motors_stopped", true}, {"padding", std::string(kEchoedAnswerLimit, 'p')}};
  auto entry = node_entry(answered(200, big), BroadcastKind::Stop);
  CHECK(entry["ok"] == true);
  CHECK_FALSE(entry.contains("response"));
  CHECK(entry["response_bytes"].get<std::size_t>() > kEchoedAnswerLimit);
}
