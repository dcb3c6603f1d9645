// runtime.r2r.peers_file (docs/protocol.md §11, README "A fleet of ten robots"): the fleet's enrolled robots, one file
// every robot reads, written by `rcanctl fleet enroll` and edited by hand. YAML, as the robot's own config (comments, no
// quoting of names, one line per key; JSON is YAML too, so a generated JSON file reads as well):
//
//   peers:
//     - name: alpha                   # the robot's name: its source_id and signature key_id
//       public_key: 3q2+7w...=        # Ed25519, 32 bytes, base64 (or public_key_file: PEM, relative to this file)
//       role: USER                    # what its signed messages may do (default USER)
//
// The entries have the shape of runtime.r2r.peers[] entries. Every problem is reported as file:line:column.
#pragma once

#include <nlohmann/json.hpp>

#include <filesystem>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "libs/r2r_wire/ed25519_key.hpp"
#include "rcand/sdk/scope.hpp"

namespace rcand::r2r_wire {

struct PeerKey {
  std::string name;                  // the peer's robot name; also the key_id it signs with
  sdk::Role role = sdk::Role::User;  // what a message signed by it may do
  std::shared_ptr<const Ed25519Key> key;
};

struct LoadedPeers {
  std::vector<PeerKey> peers;
  std::vector<std::string> where;  // per peer, "file:line:column" of its entry
};

// Reads and checks `file`: a mapping with `peers`, a list of {name, public_key | public_key_file, role}; names unique;
// each key decodes to an Ed25519 public key. Throws std::invalid_argument "file:line:column: peers[2].public_key: ..."
// (never a key's bytes).
LoadedPeers load_peers_file(const std::filesystem::path& file);

// The peers this robot accepts: the inline runtime.r2r.peers (their config positions in `inline_where`, e.g.
// "runtime.r2r.peers[1]") and the file's. A name in both is an error naming both places (std::invalid_argument).
std::vector<PeerKey> merge_peers(std::vector<PeerKey> inline_peers, const std::vector<std::string>& inline_where,
                                 LoadedPeers from_file);

// The file as written, checked as load_peers_file checks it ({"peers":[...]}); a file that does not exist is
// {"peers":[]} when `missing_ok`. For rcanctl fleet enroll|revoke|list.
nlohmann::json read_peers_document(const std::filesystem::path& file, bool missing_ok);

// Writes `doc` as YAML atomically: a temporary file in the same directory, flushed to disk, renamed over `file`; mode
// 0644 (public keys are not secret: every robot reads it). Throws std::runtime_error saying what failed.
void write_peers_document(const std::filesystem::path& file, const nlohmann::json& doc);

}  // namespace rcand::r2r_wire
