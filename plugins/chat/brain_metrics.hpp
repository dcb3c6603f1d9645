// chat's brain calls as Prometheus metrics (rcand/sdk/interfaces/metrics.hpp), recorded once per call of the chain:
//   rcand_chat_brain_calls_total{provider, model, outcome}   outcome: answered, fallback (answered after an earlier
//                                                            brain of the chain failed), error, timeout (failed when
//                                                            the call's deadline had passed)
//   rcand_chat_brain_call_duration_seconds{provider, model}  how long each call took, whatever its outcome
// Nothing is recorded when nothing offers sdk::Metrics (rcand without telemetry, a fake host without it).
#pragma once

#include <rcand/sdk/context.hpp>
#include <rcand/sdk/interfaces/brain.hpp>

#include <chrono>
#include <string_view>

namespace rcand::plugins::chat {

enum class BrainOutcome { Answered, Fallback, Error, Timeout };

BrainOutcome brain_outcome(const sdk::Proposal& proposal, bool deadline_passed, bool after_failure) noexcept;
std::string_view outcome_name(BrainOutcome outcome) noexcept;

// Both families, so they show in GET /metrics before the first call. At start().
void declare_brain_metrics(const sdk::PluginContext& ctx) noexcept;
// One call of the chain to `provider`, which answered `proposal` after `elapsed`. Any thread, never blocks.
void record_brain_call(const sdk::PluginContext& ctx, std::string_view provider, const sdk::Proposal& proposal,
                       bool deadline_passed, bool after_failure, std::chrono::steady_clock::duration elapsed) noexcept;

}  // namespace rcand::plugins::chat
