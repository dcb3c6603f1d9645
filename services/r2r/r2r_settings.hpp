// runtime.r2r.*: the R2R service's own config keys (declared in r2r_settings.cpp, checked by the config's one table
// with file:line:column) and the settings read from them.
#pragma once

#include <nlohmann/json.hpp>

#include <chrono>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "rcand/sdk/interfaces/pose_source.hpp"
#include "services/r2r/message_auth.hpp"

namespace rcand::services::r2r {

// The auction's keys (bid_window_ms, cost_per_queued_task_s, max_held_tasks) are checked by this service's table too,
// so a mistake is reported with its file position, but the fleet plugin (org.rcand.fleet) reads and applies them.
struct R2rSettings {
  sdk::Pose2d origin;                                       // runtime.r2r.origin {x, y, heading_deg}: status positions
  std::chrono::milliseconds status_interval{1000};          // runtime.r2r.status_interval_ms
  std::optional<std::string> outbound_token;                // contents of runtime.r2r.token_file: sent in header.auth.token
  std::shared_ptr<const r2r_wire::Ed25519Key> private_key;  // runtime.r2r.private_key_file: signs every outbound message
  MessageAuthSettings auth;  // require_signatures, peers[] {name, public_key_file|public_key, role},
                             // replay_window_s; peers: the inline ones, then peers_file's
  // runtime.r2r.peers_file (services/r2r/peers_file.hpp), re-read on each SIGHUP reload; the inline peers stay.
  std::optional<std::filesystem::path> peers_file;
  std::vector<r2r_wire::PeerKey> inline_peers;
  std::vector<std::string> inline_where;  // "runtime.r2r.peers[i]" per inline peer
  // Memory bounds (issue 13 #14).
  std::size_t max_peers = 1024;       // runtime.r2r.max_peers: the peer table; the least recently heard goes
  double peer_expiry_s = 120.0;       // runtime.r2r.peer_expiry_s: a peer silent this long is forgotten
  std::vector<std::string> warnings;  // secrets other users may read (still used): the service logs them at start
};

// Reads `runtime_r2r` (the runtime.r2r block as JSON; relative files resolve against `base_dir`), after the table's
// check of it. Throws std::invalid_argument naming the key at fault (runtime.r2r.peers[1].public_key_file: ...), for a
// value the table refuses or a file that cannot be read - never a key's bytes.
R2rSettings load_r2r_settings(const nlohmann::json& runtime_r2r, const std::filesystem::path& base_dir);

// The peers `settings` accepts with its peers file read again (a SIGHUP reload). Throws std::invalid_argument with the
// file's line (the caller keeps the table it has).
std::vector<r2r_wire::PeerKey> reload_peers(const R2rSettings& settings);

}  // namespace rcand::services::r2r
