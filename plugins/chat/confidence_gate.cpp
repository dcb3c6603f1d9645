#include "confidence_gate.hpp"

#include <algorithm>
#include <cmath>

namespace rcand::plugins::chat {

std::vector<ConfidenceGate> read_confidence_gates(const sdk::ConfigView& robot_config, std::vector<std::string>* ignored) {
  const auto& raw = robot_config.raw();
  const auto agent = raw.find("agent");
  if (agent == raw.end() || !agent->is_object() || !agent->contains("confidence_gates")) return {};
  const auto& list = agent->at("confidence_gates");
  if (list.is_null()) return {};
  if (!list.is_array()) throw sdk::ConfigError("agent.confidence_gates: expected a list of gates");
  std::vector<ConfidenceGate> gates;
  for (std::size_t i = 0; i < list.size(); ++i) {
    const std::string where = "agent.confidence_gates[" + std::to_string(i) + "]";
    const auto& item = list[i];
    if (!item.is_object()) throw sdk::ConfigError(where + ": expected a mapping with min_confidence and on_fail");
    ConfidenceGate gate;
    const auto min = item.find("min_confidence");
    if (min == item.end() || !min->is_number() || !std::isfinite(min->get<double>()) || min->get<double>() < 0 ||
        min->get<double>() > 1)
      throw sdk::ConfigError(where + ".min_confidence: required, a number in [0, 1]");
    gate.min_confidence = min->get<double>();
    if (const auto on_fail = item.find("on_fail"); on_fail != item.end()) {
      const std::string text = on_fail->is_string() ? on_fail->get<std::string>() : "";
      if (text == "block") gate.on_fail = ConfidenceGate::OnFail::Block;
      else if (text == "escalate") gate.on_fail = ConfidenceGate::OnFail::Escalate;
      else if (text == "allow") gate.on_fail = ConfidenceGate::OnFail::Allow;
      else throw sdk::ConfigError(where + ".on_fail: one of block, escalate, allow");
    }
    if (const auto scope = item.find("scope"); scope != item.end() && scope->is_string() && *scope == "safety") {
      if (ignored != nullptr)
        ignored->push_back(where +
                           ": scope 'safety' (the reference runtime's) would gate stops, which chat never holds "
                           "back; this gate is ignored");
      continue;
    }
    if (const auto scope = item.find("scope"); scope != item.end()) {
      gate.scope = scope->is_string() ? sdk::parse_scope(scope->get<std::string>()) : std::nullopt;
      if (!gate.scope) throw sdk::ConfigError(where + ".scope: a scope name (status, control, config, ...)");
    }
    if (const auto caps = item.find("capabilities"); caps != item.end()) {
      if (!caps->is_array()) throw sdk::ConfigError(where + ".capabilities: a list of capability names");
      for (const auto& name : *caps) {
        if (!name.is_string()) throw sdk::ConfigError(where + ".capabilities: a list of capability names");
        gate.capabilities.push_back(name.get<std::string>());
      }
    }
    gates.push_back(std::move(gate));
  }
  return gates;
}

GateVerdict apply_confidence_gates(const std::vector<ConfidenceGate>& gates, std::optional<double> confidence, sdk::Scope scope,
                                   const std::string& capability) {
  GateVerdict verdict;
  for (const auto& gate : gates) {
    if (gate.scope && *gate.scope != scope) continue;
    if (!gate.capabilities.empty() &&
        std::find(gate.capabilities.begin(), gate.capabilities.end(), capability) == gate.capabilities.end())
      continue;
    const bool meets = confidence && std::isfinite(*confidence) && *confidence >= gate.min_confidence;
    if (meets) continue;
    if (verdict.passed || gate.on_fail > verdict.outcome) {
      verdict.outcome = gate.on_fail;
      verdict.threshold = gate.min_confidence;
    }
    verdict.passed = false;
  }
  return verdict;
}

const char* on_fail_name(ConfidenceGate::OnFail on_fail) noexcept {
  switch (on_fail) {
    case ConfidenceGate::OnFail::Allow: return "allow";
    case ConfidenceGate::OnFail::Escalate: return "escalate";
    case ConfidenceGate::OnFail::Block: return "block";
  }
  return "block";
}

}  // namespace rcand::plugins::chat
