// Who a caller is when it claims a shared slot (libs/base/slot_table.hpp: telemetry sockets, R2R sockets, streamed
// answers; docs/protocol.md §7.17), and the answer when it gets none. OWNER and CREATOR count against neither cap and
// may take the reserved slots, so no guest can lock an operator out. Anyone below is capped per principal and per
// client address (many credentials on one host are still one host). In auth mode open everyone is the same CREATOR
// principal and nobody can be told to be the owner: only the per-address cap applies, to everyone, and the reserved
// slots are open to all.
#pragma once

#include <rcand/sdk/scope.hpp>

#include <string>
#include <string_view>

#include "libs/base/slot_table.hpp"
#include "libs/http/response.hpp"

namespace rcand::kernel {

SlotHolder slot_holder(std::string principal, sdk::Role role, bool open_mode, std::string address);

// How a refusal reads for one kind of slot.
struct SlotWords {
  std::string_view what;           // "telemetry WebSocket connections"
  std::string_view capacity_key;   // "runtime.telemetry.max_clients"
  std::string_view principal_key;  // "runtime.telemetry.max_clients_per_principal"
  std::string_view address_key;    // "runtime.telemetry.max_clients_per_address"
  std::string_view reserved_key;   // "runtime.telemetry.reserved_clients"
  std::string_view cap_code = "TOO_MANY_CONNECTIONS";
  std::string_view reserved_code = "SLOTS_RESERVED";
};

// The refused claim's answer, with Retry-After: 503 UNAVAILABLE when full, 429 `cap_code` over a cap (naming the
// principal or the address and how many it holds), 503 `reserved_code` when only reserved slots are left.
http::Response slot_refusal(const SlotTable::Claim& claim, const SlotWords& words, const SlotHolder& holder, sdk::Role role);

}  // namespace rcand::kernel
