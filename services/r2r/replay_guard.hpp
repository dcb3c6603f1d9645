// Remembers recently accepted signed messages, so a copy replayed inside the replay window (or the same broadcast
// arriving over a second transport) is handled once. Keyed on replay_key(): a digest of the canonical signed message,
// never on its text, so no other spelling of the same message (JSON whitespace, number or escape forms) or of its
// signature counts as new. Not thread-safe: the node locks around it.
//
// Across a restart the memory is gone; the node therefore refuses every signed message timestamped before it started
// (R2rNode, code 103), so nothing signed before a restart can be replayed after it.
#pragma once

#include <nlohmann/json.hpp>

#include <cstddef>
#include <string>
#include <unordered_map>

namespace rcand::services::r2r {

// The identity of a signed message for replay purposes: SHA-256 (32 raw bytes) of its signing input (the canonical
// message without header.signature), which is what the signature covers.
std::string replay_key(const nlohmann::json& message);

class ReplayGuard {
 public:
  // `window_s`: how long a signature is remembered (the replay window plus the allowed future skew: older copies are
  // refused by their timestamp anyway). `max_entries` bounds memory under a flood.
  explicit ReplayGuard(double window_s, std::size_t max_entries = 100000) : window_s_(window_s), max_entries_(max_entries) {}

  // True the first time `key` (a replay_key) is seen (and records it); false for a copy.
  bool first_time(const std::string& key, double now_s);
  std::size_t size() const noexcept { return seen_.size(); }

 private:
  void prune(double now_s);
  double window_s_;
  std::size_t max_entries_;
  std::unordered_map<std::string, double> seen_;  // replay key -> when first seen
  double last_prune_s_ = 0.0;
};

}  // namespace rcand::services::r2r
