// What a brain returns, made safe to store, log, answer and act on: the one function every sdk::Proposal passes
// through on chat's answer path (Chat::ask_brains, for every brain - HTTP, vendor or grammar - before anything reads
// it), and ModelBrain::propose for its own answer. A model is hostile input: a model server may echo the API key it
// was sent, a confidence may be a 200 KB string, a suggestion a megabyte.
//   - Secrets: every configured API key is replaced by "[api key]" in every text - raw_text, reasoning, suggestions,
//     error, brain, model - and in every string and object key inside the action (which is dispatched, stored and
//     answered). Replaced before anything is cut, so a bound never leaves half a key behind.
//   - Bounds: each text is cut at a UTF-8 character boundary to its bound below; at most kMaxSuggestions suggestions.
//     An action over kMaxActionBytes as JSON, or a confidence outside [0, 1], fails the proposal (the chain moves on):
//     no request a client could send is that large, and an out-of-range confidence is no probability.
#pragma once

#include <rcand/sdk/interfaces/brain.hpp>

#include <cstddef>
#include <string>
#include <vector>

namespace rcand::plugins::chat {

inline constexpr std::size_t kMaxReplyBytes = 4000;      // raw_text, reasoning
inline constexpr std::size_t kMaxSuggestionBytes = 200;  // each suggestion
inline constexpr std::size_t kMaxSuggestions = 3;
inline constexpr std::size_t kMaxErrorBytes = 1000;  // a failed brain's error (in attempts, the thought, log lines)
inline constexpr std::size_t kMaxNameBytes = 128;    // brain, model
inline constexpr std::size_t kMaxActionBytes = 8192;

// `text` with every occurrence of each non-empty secret replaced by "[api key]".
std::string redact_secrets(std::string text, const std::vector<std::string>& secrets);

// The proposal with every secret redacted and every text bounded (above); a failed one keeps no action.
sdk::Proposal guard_proposal(sdk::Proposal p, const std::vector<std::string>& secrets);

}  // namespace rcand::plugins::chat
