#include "libs/swarm/broadcast_report.hpp"

#include "libs/base/bounded_text.hpp"

namespace rcand::swarm {

using nlohmann::json;

namespace {

// A peer's answer is untrusted input: a field it sends with the wrong type is that node's failure, never an exception
// on the broadcasting robot.
enum class Flag { Absent, True, False, Malformed };

Flag boolean_field(const json& body, const char* key) {
  const auto found = body.find(key);
  if (found == body.end()) return Flag::Absent;
  if (!found->is_boolean()) return Flag::Malformed;
  return found->get<bool>() ? Flag::True : Flag::False;
}

// Quoted peer text (error, code, reason) stays short and printable in our report and in rcanctl's table.
json peer_text(const json& value) { return value.is_string() ? json(bounded_text(value.get_ref<const std::string&>())) : json(); }

json malformed(json entry, const char* key) {
  entry["error"] = std::string("malformed answer: \"") + key + "\" is not a boolean";
  entry["code"] = "MALFORMED_ANSWER";
  return entry;
}

}  // namespace

json node_entry(const PeerResult& result, BroadcastKind kind) {
  json entry{{"name", result.name}, {"address", result.address},
             {"ok", false},         {"http_status", nullptr},
             {"executed", false},   {"latency_ms", std::round(result.latency_ms * 1000.0) / 1000.0},
             {"error", nullptr}};
  if (!result.reachable) {
    entry["error"] = result.error.empty() ? "no answer" : result.error;
    return entry;
  }
  entry["http_status"] = result.status;
  const json body = json::parse(result.body, nullptr, false);
  const bool success = result.status >= 200 && result.status < 300;
  // The node's own answer, for the operator; a large one is summarised, not copied into every report.
  if (!body.is_discarded() && result.body.size() <= kEchoedAnswerLimit) entry["response"] = body;
  else if (!body.is_discarded()) entry["response_bytes"] = result.body.size();
  if (!success) {
    std::string message = "HTTP " + std::to_string(result.status);
    if (body.is_object() && body.contains("error") && body["error"].is_string()) message = peer_text(body["error"]);
    if (body.is_object() && body.contains("code") && body["code"].is_string()) entry["code"] = peer_text(body["code"]);
    entry["error"] = message;
    return entry;
  }
  if (!body.is_object()) {
    entry["error"] = "answer is not a JSON object";
    return entry;
  }
  const Flag ack = boolean_field(body, "ack");
  const Flag executed = boolean_field(body, "executed");
  if (ack == Flag::Malformed) return malformed(std::move(entry), "ack");
  if (executed == Flag::Malformed) return malformed(std::move(entry), "executed");
  if (ack == Flag::True && executed == Flag::False) {
    entry["ok"] = true;  // acknowledged, deliberately not executed (§15.5: e-stop is always local)
    if (body.contains("reason")) entry["reason"] = peer_text(body["reason"]);
    return entry;
  }
  if (kind == BroadcastKind::Stop) {
    const Flag stopped = boolean_field(body, "motors_stopped");
    if (stopped == Flag::Malformed) return malformed(std::move(entry), "motors_stopped");
    entry["motors_stopped"] = stopped == Flag::True;
    entry["executed"] = true;
    entry["ok"] = stopped == Flag::True;
    if (stopped != Flag::True) entry["error"] = "the node latched its e-stop but did not confirm every motor stopped";
    return entry;
  }
  entry["ok"] = true;
  entry["executed"] = executed != Flag::False;
  return entry;
}

json broadcast_document(std::vector<json> nodes) {
  std::size_t ok = 0;
  for (const auto& node : nodes) {
    const auto found = node.find("ok");
    ok += found != node.end() && found->is_boolean() && found->get<bool>() ? 1 : 0;
  }
  const std::size_t total = nodes.size();
  return {{"broadcast", true}, {"nodes", std::move(nodes)}, {"summary", {{"total", total}, {"ok", ok}, {"failed", total - ok}}}};
}

}  // namespace rcand::swarm
