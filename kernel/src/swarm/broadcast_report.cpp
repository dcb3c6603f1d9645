#include "rcand/kernel/swarm/broadcast_report.hpp"

namespace rcand::kernel::swarm {

using nlohmann::json;

json node_entry(const PeerResult& result, BroadcastKind kind) {
  json entry{{"name", result.name},
             {"address", result.address},
             {"ok", false},
             {"http_status", nullptr},
             {"executed", false},
             {"latency_ms", std::round(result.latency_ms * 1000.0) / 1000.0},
             {"error", nullptr}};
  if (!result.reachable) {
    entry["error"] = result.error.empty() ? "no answer" : result.error;
    return entry;
  }
  entry["http_status"] = result.status;
  const json body = json::parse(result.body, nullptr, false);
  const bool success = result.status >= 200 && result.status < 300;
  if (!body.is_discarded()) entry["response"] = body;
  if (!success) {
    std::string message = "HTTP " + std::to_string(result.status);
    if (body.is_object() && body.contains("error") && body["error"].is_string()) message = body["error"].get<std::string>();
    if (body.is_object() && body.contains("code") && body["code"].is_string()) entry["code"] = body["code"];
    entry["error"] = message;
    return entry;
  }
  if (!body.is_object()) {
    entry["error"] = "answer is not a JSON object";
    return entry;
  }
  if (body.value("ack", false) && body.contains("executed") && body["executed"] == false) {
    entry["ok"] = true;  // acknowledged, deliberately not executed (§15.5: e-stop is always local)
    if (body.contains("reason")) entry["reason"] = body["reason"];
    return entry;
  }
  if (kind == BroadcastKind::Stop) {
    const bool stopped = body.value("motors_stopped", false);
    entry["motors_stopped"] = stopped;
    entry["executed"] = true;
    entry["ok"] = stopped;
    if (!stopped) entry["error"] = "the node latched its e-stop but did not confirm every motor stopped";
    return entry;
  }
  entry["ok"] = true;
  entry["executed"] = body.value("executed", true);
  return entry;
}

json broadcast_document(std::vector<json> nodes) {
  std::size_t ok = 0;
  for (const auto& node : nodes) ok += node.value("ok", false) ? 1 : 0;
  const std::size_t total = nodes.size();
  return {{"broadcast", true}, {"nodes", std::move(nodes)}, {"summary", {{"total", total}, {"ok", ok}, {"failed", total - ok}}}};
}

}  // namespace rcand::kernel::swarm
