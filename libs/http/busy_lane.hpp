// Who makes room when the busy lane is full (ServerOptions::busy_lane). Pure policy, so the rule is tested without
// sockets: the accept loop classifies each waiter by what it has sent so far and evicts the one this picks.
#pragma once

#include <cstddef>
#include <functional>
#include <optional>
#include <span>
#include <string_view>

#include "libs/http/request.hpp"

namespace rcand::http::detail {

// What a waiting connection has sent so far, in the order waiters are given up.
enum class PendingInput {
  Ordinary,  // a whole request line that is not a priority request: it gets 503 anyway, so nothing is lost
  Silent,    // nothing yet: a slow-loris, a flood that only connects, or a client about to send its stop
  Partial,   // the start of a request line: a client that trickles its bytes (a stop comes in one write)
  Priority,  // a priority request (the e-stop): never evicted
};

// `bytes`: the start of what the client sent. `is_priority` is ServerOptions::priority.
PendingInput classify_pending(std::string_view bytes, const std::function<bool(const Request&)>& is_priority);

struct LaneWaiter {
  std::string_view address;
  PendingInput input = PendingInput::Silent;
};

// For a newcomer from `newcomer` to a full lane (`lane` oldest first): the index of the waiter to evict, or nullopt
// to refuse the newcomer (every waiter holds a priority request). The least valuable input goes first (in the order
// of PendingInput); within it
// the newcomer's own address, then the addresses holding most of the lane, then the oldest. So a flood evicts
// itself before anyone else, and a stop already in the lane is never dropped for it.
std::optional<std::size_t> choose_eviction(std::span<const LaneWaiter> lane, std::string_view newcomer);

}  // namespace rcand::http::detail
