// The confidence gate (RCAN agent.confidence_gates[]): a brain's proposal below a gate's threshold is blocked,
// escalated to a human, or allowed anyway, as the gate says. A proposal without a confidence misses every gate it
// meets - never read as 1.0. Runs after the action is validated, so a gate can be limited to the actions that need
// a scope or touch given capabilities.
//
// Ruling (RCAN names the list, not its items): each gate is
//   {min_confidence: 0..1 (required), on_fail: block | escalate | allow (default block),
//    scope: status | control (optional: only actions needing that scope), capabilities: [names] (optional)}
// and the strictest failing gate decides (block over escalate over allow).
#pragma once

#include <rcand/sdk/config_view.hpp>
#include <rcand/sdk/scope.hpp>

#include <optional>
#include <string>
#include <vector>

namespace rcand::plugins::chat {

struct ConfidenceGate {
  enum class OnFail { Allow, Escalate, Block };  // in order of strictness
  double min_confidence = 1.0;
  OnFail on_fail = OnFail::Block;
  std::optional<sdk::Scope> scope;
  std::vector<std::string> capabilities;  // empty: every capability
};

// agent.confidence_gates of the robot config (absent: none). Throws sdk::ConfigError naming the item at fault. A gate
// of the reference runtime's `safety` scope is left out with a line in `ignored`: it would gate stops, which chat never
// holds back.
std::vector<ConfidenceGate> read_confidence_gates(const sdk::ConfigView& robot_config,
                                                  std::vector<std::string>* ignored = nullptr);

struct GateVerdict {
  bool passed = true;                                              // no gate failed
  ConfidenceGate::OnFail outcome = ConfidenceGate::OnFail::Allow;  // when not passed: what the strictest gate says
  double threshold = 0.0;                                          // that gate's min_confidence
};

GateVerdict apply_confidence_gates(const std::vector<ConfidenceGate>& gates, std::optional<double> confidence, sdk::Scope scope,
                                   const std::string& capability);

const char* on_fail_name(ConfidenceGate::OnFail on_fail) noexcept;

}  // namespace rcand::plugins::chat
