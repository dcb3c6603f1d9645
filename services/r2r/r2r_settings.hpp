// runtime.r2r.* (the keys this module reads; the config schema table validates them with file:line:column first).
#pragma once

#include <nlohmann/json.hpp>

#include <chrono>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "services/r2r/auction.hpp"
#include "services/r2r/cost_function.hpp"
#include "services/r2r/fleet_geometry.hpp"
#include "services/r2r/message_auth.hpp"

namespace rcand::kernel::r2r {

struct R2rSettings {
  FleetPose origin;                                 // runtime.r2r.origin {x, y, heading_deg}
  std::chrono::milliseconds status_interval{1000};  // runtime.r2r.status_interval_ms
  std::chrono::milliseconds bid_window{1000};       // runtime.r2r.bid_window_ms: how long an auction collects bids
  double seconds_per_task = 30.0;                   // runtime.r2r.cost_per_queued_task_s
  std::optional<std::string> outbound_token;        // contents of runtime.r2r.token_file: sent in header.auth.token
  std::shared_ptr<const Ed25519Key> private_key;    // runtime.r2r.private_key_file: signs every outbound message
  MessageAuthSettings auth;                         // require_signatures, peers[] {name, public_key_file|public_key, role},
                                                    // replay_window_s
  // Memory bounds (issue 13 #14).
  std::size_t max_peers = 1024;  // runtime.r2r.max_peers: the peer table; the least recently heard goes
  double peer_expiry_s = 120.0;  // runtime.r2r.peer_expiry_s: a peer silent this long is forgotten
  Bidder::Limits bidder;         // runtime.r2r.max_held_tasks (64); the rest fixed
  Auctioneer::Limits auctioneer;
};

// Reads `runtime_r2r` (the runtime.r2r block as JSON; relative files resolve against `base_dir`). Throws
// std::invalid_argument naming the key at fault (runtime.r2r.peers[1].public_key_file: ...) - never a key's bytes.
R2rSettings load_r2r_settings(const nlohmann::json& runtime_r2r, const std::filesystem::path& base_dir);

}  // namespace rcand::kernel::r2r
