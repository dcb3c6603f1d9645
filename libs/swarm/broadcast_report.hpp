// The per-node report of a swarm broadcast (docs/protocol.md §9):
// {"broadcast":true,"nodes":[{"name","ok","http_status","executed","latency_ms","error",...}],"summary":{"total","ok","failed"}}
// One function turns a peer's HTTP answer into its entry, for rcand's broadcasts and for rcanctl alike.
#pragma once

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstddef>
#include <string_view>
#include <vector>

#include "libs/swarm/fan_out.hpp"

namespace rcand::swarm {

enum class BroadcastKind { Stop, Command };

// A peer's answer larger than this is not copied into the report ("response_bytes" says its size instead).
inline constexpr std::size_t kEchoedAnswerLimit = 16 * 1024;

// A node's entry. ok: a 2xx answer (for a stop, also "motors_stopped": true). executed: the node ran it (false for
// the e-stop acknowledgement {"ack":true,"executed":false,"reason":"estop_active"} and for every failure).
// http_status is null and error names the transport failure when the node never answered. Adds "address",
// "code" (the node's error code), "reason", "motors_stopped" (stop) and "response" (the node's JSON answer).
// Never throws on what a peer sends: a field of the wrong type ("motors_stopped": "yes") makes that node a failure
// with code MALFORMED_ANSWER; quoted peer text is bounded.
nlohmann::json node_entry(const PeerResult& result, BroadcastKind kind);

// The whole document; `nodes` keep their order.
nlohmann::json broadcast_document(std::vector<nlohmann::json> nodes);

}  // namespace rcand::swarm
