#include "services/swarm_broadcast/swarm_table.hpp"

#include <boost/asio/ip/address.hpp>

#include <algorithm>
#include <cmath>

#include "kernel/api/answers.hpp"
#include "libs/base/bounded_text.hpp"
#include "libs/base/json_body.hpp"
#include "libs/swarm/broadcast_report.hpp"
#include "services/swarm_broadcast/swarm_metrics.hpp"

namespace rcand::services {
namespace {

using nlohmann::json;

// A status probe and a per-node stop each get what a broadcast stop gives one peer (docs/protocol.md §9.6).
constexpr std::chrono::milliseconds kNodeTimeout{300};
constexpr std::string_view kPrefix = "/api/swarm/";
constexpr std::string_view kStopSuffix = "/stop";

// A table row from the node's GET /api/status answer (or its failure).
json status_row(const swarm::SwarmNode& node, bool self, const swarm::PeerResult& result) {
  json row{{"name", node.name},  {"address", node.address()},
           {"tags", node.tags},  {"self", self},
           {"reachable", false}, {"http_status", nullptr},
           {"state", nullptr},   {"estopped", nullptr},
           {"ruri", nullptr},    {"latency_ms", std::round(result.latency_ms * 10.0) / 10.0}};
  if (!result.reachable) {
    row["error"] = result.error.empty() ? "no answer" : result.error;
    row["code"] = "SWARM_NODE_UNREACHABLE";
    return row;
  }
  row["reachable"] = true;
  row["http_status"] = result.status;
  const JsonBody body = parse_json_body(result.body);
  const json& doc = body.value;
  if (result.status != 200 || !body.error.empty() || !doc.is_object()) {
    const std::string code =
        doc.is_object() && doc.contains("code") && doc["code"].is_string() ? doc["code"].get<std::string>() : "";
    row["error"] = "GET /api/status answered " + std::to_string(result.status) + (code.empty() ? "" : " " + code) +
                   (result.status == 401 || result.status == 403 ? " (check this node's token in swarm.yaml)" : "");
    row["code"] = code.empty() ? "SWARM_NODE_FAILED" : code;
    return row;
  }
  for (const char* key : {"state", "ruri"})
    if (doc.contains(key) && doc[key].is_string()) row[key] = doc[key];
  if (doc.contains("estopped") && doc["estopped"].is_boolean()) row["estopped"] = doc["estopped"];
  return row;
}

}  // namespace

bool is_this_robot(const swarm::SwarmNode& node, const kernel::ServiceHost& host) {
  if (node.port != host.port.load()) return false;
  boost::system::error_code ec;
  const auto listen = boost::asio::ip::make_address(host.config.runtime.listen_address, ec);
  if (ec) return false;
  for (const std::string& candidate : {node.host, node.ip.value_or("")}) {
    if (candidate == "localhost" && (listen.is_loopback() || listen.is_unspecified())) return true;
    const auto address = boost::asio::ip::make_address(candidate, ec);
    if (ec) continue;
    if (address == listen || (address.is_loopback() && (listen.is_loopback() || listen.is_unspecified()))) return true;
  }
  return false;
}

void SwarmTable::add_routes(kernel::Router& router) {
  router.add({"GET", "/api/swarm", sdk::Scope::Status},
             [this](kernel::Call& call, kernel::Reply reply) { list(call, std::move(reply)); });
  router.add(
      // Audited by the handler (before the stop is forwarded), once it knows whether the node exists.
      {.method = "POST", .path = std::string(kPrefix) + "*", .scope = sdk::Scope::Status, .rate_limited = false},
      [this](kernel::Call& call, kernel::Reply reply) { stop_node(call, std::move(reply)); });
  declare_swarm_metrics(host_.plugin_services);
}

void SwarmTable::list(kernel::Call&, kernel::Reply reply) {
  auto nodes = std::make_shared<std::vector<swarm::SwarmNode>>(swarm_.now().nodes);
  std::vector<swarm::PeerRequest> probes;
  for (const auto& node : *nodes) {
    auto probe = swarm::peer_request(node, "GET", "/api/status");
    probe.body_limit = swarm::kStopAnswerLimit;
    probe.headers.emplace_back("X-Swarm-Forwarded", host_.registry.identity().ruri);
    probes.push_back(std::move(probe));
  }
  auto answer = [this, nodes, reply = std::move(reply)](std::vector<swarm::PeerResult> results) {
    json rows = json::array();
    std::size_t reachable = 0;
    for (std::size_t i = 0; i < nodes->size() && i < results.size(); ++i) {
      rows.push_back(status_row((*nodes)[i], is_this_robot((*nodes)[i], host_), results[i]));
      if (results[i].reachable) ++reachable;
    }
    reply(kernel::json_response(200,
                                {{"nodes", std::move(rows)}, {"summary", {{"total", nodes->size()}, {"reachable", reachable}}}}));
  };
  if (probes.empty()) return answer({});
  fan_out_.run(std::move(probes), kNodeTimeout, std::move(answer));
}

void SwarmTable::stop_node(kernel::Call& call, kernel::Reply reply) {
  const std::string& path = call.request.path;
  const bool shaped = path.size() > kPrefix.size() + kStopSuffix.size() && path.ends_with(kStopSuffix);
  const std::string name = shaped ? path.substr(kPrefix.size(), path.size() - kPrefix.size() - kStopSuffix.size()) : "";
  const auto& swarm = swarm_.now();
  const swarm::SwarmNode* node = shaped ? swarm.find(name) : nullptr;
  if (node == nullptr) return refuse_unknown(call, reply, shaped, name);
  // docs/protocol.md §6.3: audited before it is forwarded, in the stops' retention (never displacing a command).
  call.audit_seq =
      host_.audit.begin(call.principal, call.message_id, call.request.method + " " + path, nullptr, kernel::AuditRetention::Stop);
  // Forwarded like a broadcast stop (docs/protocol.md §9.2): with the node's own token, never forwarded again.
  const JsonBody body = parse_json_body(call.request.body);
  std::string reason = "stopped from the swarm table of " + host_.registry.identity().ruri + " by " + call.principal;
  if (body.error.empty() && body.value.is_object() && body.value.contains("reason") && body.value["reason"].is_string())
    reason += ": " + bounded_text(body.value["reason"].get<std::string>(), 200);
  auto request = swarm::peer_request(*node, "POST", "/api/stop", json{{"reason", reason}}.dump());
  request.body_limit = swarm::kStopAnswerLimit;
  request.headers.emplace_back("X-Swarm-Forwarded", host_.registry.identity().ruri);
  request.headers.emplace_back("X-Message-Id", call.message_id);
  fan_out_.run(
      {std::move(request)}, kNodeTimeout,
      [audit = &host_.audit, directory = &host_.plugin_services, seq = call.audit_seq, name = node->name,
       reply = std::move(reply)](std::vector<swarm::PeerResult> results) {
        const json entry = results.empty() ? json{{"name", name}, {"ok", false}, {"http_status", nullptr}, {"error", "not sent"}}
                                           : swarm::node_entry(results.front(), swarm::BroadcastKind::Stop);
        record_node_stop(*directory, entry);
        const bool ok = entry.value("ok", false) == true;
        const bool answered = entry.contains("http_status") && !entry["http_status"].is_null();
        const std::string error = entry.contains("error") && entry["error"].is_string() ? entry["error"].get<std::string>() : "";
        audit->finish(seq, ok ? "ok" : "error", "node " + name + (ok ? ": motors stopped" : ": " + error));
        if (ok) return reply(kernel::json_response(200, {{"node", entry}}));
        reply(kernel::error_response(
            502, answered ? "SWARM_NODE_FAILED" : "SWARM_NODE_UNREACHABLE",
            "node '" + name + "' " + (answered ? "did not confirm the stop: " : "could not be reached: ") + error,
            {{"node", entry}}));
      });
}

// Not a stop of any node: audited (a stop request all the same) and answered 404 while the principal's budget
// lasts; beyond it 429, logged, not audited - so no principal can flood the audit log with names that stop nothing.
void SwarmTable::refuse_unknown(kernel::Call& call, const kernel::Reply& reply, bool shaped, const std::string& name) {
  const std::string& path = call.request.path;
  if (const auto wait = unknown_node_limit_.admit(call.principal, host_.clock.now_us())) {
    const auto retry_after_s = std::max<std::int64_t>(1, (wait->count() + 999) / 1000);
    if (const auto verdict = refusal_log_.admit(call.principal); verdict.log)
      logger("swarm")->warn("POST {} by {}: no such swarm node, over {} a second (429){}", bounded_text(path, 200),
                            call.principal, kUnknownNodePerSecond,
                            verdict.suppressed ? " (" + std::to_string(verdict.suppressed) + " more not logged)" : "");
    auto response = kernel::error_response(
        429, "RATE_LIMITED",
        "too many stops of unknown swarm nodes from principal '" + call.principal + "' (stops of known nodes are never limited)",
        {{"retry_after_s", retry_after_s}});
    response.headers.emplace_back("Retry-After", std::to_string(retry_after_s));
    return reply(std::move(response));
  }
  const auto seq =
      host_.audit.begin(call.principal, call.message_id, call.request.method + " " + path, nullptr, kernel::AuditRetention::Stop);
  host_.audit.finish(seq, "error", shaped ? "no swarm node of that name" : "not a swarm route");
  if (!shaped)
    return reply(
        kernel::error_response(404, "NOT_FOUND", "no route " + bounded_text(path, 200) + "; POST /api/swarm/<node>/stop"));
  reply(kernel::error_response(404, "SWARM_NODE_NOT_FOUND", "no node '" + bounded_text(name, 200) + "' in the swarm file",
                               {{"field", "node"}, {"known_nodes", swarm_.now().names()}}));
}

}  // namespace rcand::services
