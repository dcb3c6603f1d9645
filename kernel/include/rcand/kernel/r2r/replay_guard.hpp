// Remembers the signatures of recently accepted signed messages, so a copy replayed inside the replay window (or the
// same broadcast arriving over a second transport) is handled once. Not thread-safe: the node locks around it.
#pragma once

#include <cstddef>
#include <string>
#include <unordered_map>

namespace rcand::kernel::r2r {

class ReplayGuard {
 public:
  // `window_s`: how long a signature is remembered (the replay window plus the allowed future skew: older copies are
  // refused by their timestamp anyway). `max_entries` bounds memory under a flood.
  explicit ReplayGuard(double window_s, std::size_t max_entries = 100000) : window_s_(window_s), max_entries_(max_entries) {}

  // True the first time `signature` is seen (and records it); false for a copy.
  bool first_time(const std::string& signature, double now_s);
  std::size_t size() const noexcept { return seen_.size(); }

 private:
  void prune(double now_s);
  double window_s_;
  std::size_t max_entries_;
  std::unordered_map<std::string, double> seen_;  // signature -> when first seen
  double last_prune_s_ = 0.0;
};

}  // namespace rcand::kernel::r2r
