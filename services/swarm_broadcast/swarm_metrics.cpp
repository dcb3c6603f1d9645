#include "services/swarm_broadcast/swarm_metrics.hpp"

#include <rcand/sdk/interfaces/metrics.hpp>

#include <array>

namespace rcand::services {
namespace {

constexpr std::array<std::string_view, 2> kBroadcastLabels{"kind", "result"};
constexpr sdk::MetricFamily kBroadcasts{"rcand_swarm_broadcasts_total", sdk::MetricType::Counter,
                                        "swarm broadcasts sent by this robot, by kind and whether every node was ok",
                                        kBroadcastLabels};
constexpr std::array<std::string_view, 2> kNodeLabels{"kind", "outcome"};
constexpr sdk::MetricFamily kNodeResults{"rcand_swarm_node_results_total", sdk::MetricType::Counter,
                                         "swarm nodes reached by this robot's broadcasts and per-node stops, by outcome",
                                         kNodeLabels};

bool flag(const nlohmann::json& node, const char* key, bool otherwise) {
  const auto it = node.find(key);
  return it != node.end() && it->is_boolean() ? it->get<bool>() : otherwise;
}

std::string_view node_outcome(const nlohmann::json& node) {
  if (!node.is_object()) return "failed";
  if (flag(node, "ok", false)) return flag(node, "executed", true) ? "ok" : "not_executed";
  const auto status = node.find("http_status");
  return status == node.end() || status->is_null() ? "unreachable" : "failed";
}

}  // namespace

void declare_swarm_metrics(const kernel::ServiceDirectory& directory) noexcept {
  if (const auto* metrics = sdk::find<sdk::Metrics>(directory)) {
    metrics->declare(kBroadcasts);
    metrics->declare(kNodeResults);
  }
}

void record_broadcast(const kernel::ServiceDirectory& directory, std::string_view kind, const nlohmann::json& nodes) noexcept {
  const auto* metrics = sdk::find<sdk::Metrics>(directory);
  if (metrics == nullptr || !nodes.is_array()) return;
  std::size_t ok = 0;
  for (const auto& node : nodes) {
    const auto outcome = node_outcome(node);
    if (outcome == "ok" || outcome == "not_executed") ++ok;
    metrics->add(kNodeResults, {kind, outcome});
  }
  metrics->add(kBroadcasts, {kind, ok == nodes.size() ? "ok" : ok == 0 ? "failed" : "partial"});
}

void record_node_stop(const kernel::ServiceDirectory& directory, const nlohmann::json& node) noexcept {
  if (const auto* metrics = sdk::find<sdk::Metrics>(directory)) metrics->add(kNodeResults, {"node_stop", node_outcome(node)});
}

}  // namespace rcand::services
