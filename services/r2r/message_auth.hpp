// Who sent an R2R message, and may they (docs/protocol.md §11, README "R2R"): a shared token in header.auth.token (checked by the
// robot's Authenticator, like an HTTP bearer), a principal the transport authenticated (WebSocket upgrade), or an
// Ed25519 signature in header.signature {"key_id","sig"} over the canonical message without the signature, verified
// against the configured peer keys (libs/r2r_wire). Nothing here logs a token or key.
#pragma once

#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "kernel/auth/authenticator.hpp"
#include "libs/r2r_wire/envelope.hpp"
#include "libs/r2r_wire/peers_file.hpp"

namespace rcand::services::r2r {

inline constexpr double kDefaultReplayWindowS = 30.0;  // signed messages older than this are refused
inline constexpr double kDefaultFutureSkewS = 5.0;     // ... and so are ones this far in the future

struct MessageAuthSettings {
  bool require_signatures = false;
  std::vector<r2r_wire::PeerKey> peers;
  double replay_window_s = kDefaultReplayWindowS;
  double future_skew_s = kDefaultFutureSkewS;
};

struct AuthFailure {
  std::string message;  // safe to send back in the 103 error and to log
};

class MessageAuthenticator {
 public:
  MessageAuthenticator(const kernel::Authenticator& tokens, MessageAuthSettings settings);

  // The principal of a parsed message, checked for `needed`. Order: a signature when present (must verify; it names
  // the principal), else required signatures -> failure, else header.auth.token, else the transport's principal.
  // `raw` is the message as received (for the signature input); now_s = wall clock, Unix seconds.
  std::variant<kernel::Principal, AuthFailure> authorize(const r2r_wire::Envelope& envelope, const nlohmann::json& raw,
                                                         const std::optional<kernel::Principal>& transport_principal,
                                                         sdk::Scope needed, double now_s) const;
  const MessageAuthSettings& settings() const noexcept { return settings_; }
  // A SIGHUP reload (runtime.r2r.peers_file): from now on signatures are checked against `peers`, all at once.
  void replace_peers(std::vector<r2r_wire::PeerKey> peers);
  std::size_t peer_count() const;

 private:
  std::variant<kernel::Principal, AuthFailure> verify_signature(const r2r_wire::Envelope& envelope, const nlohmann::json& raw,
                                                                double now_s) const;
  std::shared_ptr<const std::vector<r2r_wire::PeerKey>> current_peers() const;
  const kernel::Authenticator& tokens_;
  MessageAuthSettings settings_;  // its peers as at start; peers_ is the table in force
  mutable std::mutex peers_mutex_;
  std::shared_ptr<const std::vector<r2r_wire::PeerKey>> peers_;
};

// The scope a message type needs from its sender: status/error need `status`, the rest `control`.
sdk::Scope required_scope(r2r_wire::MessageType type) noexcept;

}  // namespace rcand::services::r2r
