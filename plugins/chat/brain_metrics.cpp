#include "brain_metrics.hpp"

#include <rcand/sdk/interfaces/metrics.hpp>

#include <array>

namespace rcand::plugins::chat {
namespace {

constexpr std::array<std::string_view, 3> kCallLabels{"provider", "model", "outcome"};
constexpr sdk::MetricFamily kBrainCalls{"rcand_chat_brain_calls_total", sdk::MetricType::Counter,
                                        "calls of chat's brains, by provider, model and outcome", kCallLabels};
// From the embedded grammar (well under a millisecond) to a cold model load near chat's deadline.
constexpr std::array<double, 13> kLatencyBounds{0.001, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1, 2.5, 5, 10, 30};
constexpr std::array<std::string_view, 2> kLatencyLabels{"provider", "model"};
constexpr sdk::MetricFamily kBrainLatency{"rcand_chat_brain_call_duration_seconds", sdk::MetricType::Histogram,
                                          "time each call of a chat brain took, answered or not", kLatencyLabels, kLatencyBounds};

}  // namespace

BrainOutcome brain_outcome(const sdk::Proposal& proposal, bool deadline_passed, bool after_failure) noexcept {
  if (proposal.error.empty()) return after_failure ? BrainOutcome::Fallback : BrainOutcome::Answered;
  return deadline_passed ? BrainOutcome::Timeout : BrainOutcome::Error;
}

std::string_view outcome_name(BrainOutcome outcome) noexcept {
  switch (outcome) {
    case BrainOutcome::Answered: return "answered";
    case BrainOutcome::Fallback: return "fallback";
    case BrainOutcome::Error: return "error";
    case BrainOutcome::Timeout: return "timeout";
  }
  return "error";
}

void declare_brain_metrics(const sdk::PluginContext& ctx) noexcept {
  if (const auto* metrics = sdk::find<sdk::Metrics>(ctx)) {
    metrics->declare(kBrainCalls);
    metrics->declare(kBrainLatency);
  }
}

void record_brain_call(const sdk::PluginContext& ctx, std::string_view provider, const sdk::Proposal& proposal,
                       bool deadline_passed, bool after_failure, std::chrono::steady_clock::duration elapsed) noexcept {
  const auto* metrics = sdk::find<sdk::Metrics>(ctx);
  if (metrics == nullptr) return;
  const std::string_view model = proposal.model.empty() ? std::string_view("unknown") : std::string_view(proposal.model);
  metrics->add(kBrainCalls, {provider, model, outcome_name(brain_outcome(proposal, deadline_passed, after_failure))});
  metrics->observe(kBrainLatency, {provider, model}, std::chrono::duration<double>(elapsed).count());
}

}  // namespace rcand::plugins::chat
