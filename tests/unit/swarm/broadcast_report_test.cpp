// The per-node entries of notes §9 from peers' answers.
#include <doctest/doctest.h>

#include "rcand/kernel/swarm/broadcast_report.hpp"

using namespace rcand::kernel::swarm;
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
