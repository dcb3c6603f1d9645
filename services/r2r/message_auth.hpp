// Who sent an R2R message, and may they (docs/protocol.md §11, README "R2R"): a shared token in header.auth.token (checked by the
// robot's Authenticator, like an HTTP bearer), a principal the transport authenticated (WebSocket upgrade), or an
// Ed25519 signature in header.signature {"key_id","sig"} over the canonical message without the signature, verified
// against the configured peer keys. Keys are OpenSSL EVP objects; nothing here logs a token or key.
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
#include "services/r2r/envelope.hpp"

namespace rcand::kernel::r2r {

inline constexpr double kDefaultReplayWindowS = 30.0;  // signed messages older than this are refused
inline constexpr double kDefaultFutureSkewS = 5.0;     // ... and so are ones this far in the future

// An Ed25519 key (public, or a private key that can also sign). Move-only; owns its EVP_PKEY.
class Ed25519Key {
 public:
  // PEM (PUBLIC KEY / PRIVATE KEY) text, or 32 raw key bytes in standard base64. Throws std::invalid_argument
  // saying what is wrong (never echoing the key).
  static Ed25519Key public_from_text(std::string_view pem_or_base64);
  static Ed25519Key private_from_text(std::string_view pem_or_base64);
  static Ed25519Key public_from_file(const std::filesystem::path& file);
  static Ed25519Key private_from_file(const std::filesystem::path& file);
  static Ed25519Key generate();  // a fresh private key (tests, `rcanctl r2r keygen`)

  Ed25519Key(Ed25519Key&&) noexcept;
  Ed25519Key& operator=(Ed25519Key&&) noexcept;
  ~Ed25519Key();

  bool is_private() const noexcept { return private_; }
  std::string sign(std::string_view data) const;  // 64-byte signature; throws std::logic_error on a public key
  bool verify(std::string_view data, std::string_view signature) const noexcept;
  std::string public_base64() const;  // 32 raw bytes, base64
  std::string public_pem() const;
  std::string private_pem() const;  // throws std::logic_error on a public key

 private:
  Ed25519Key(void* pkey, bool is_private) noexcept;
  void* pkey_ = nullptr;  // EVP_PKEY*
  bool private_ = false;
};

struct PeerKey {
  std::string name;                  // the peer's robot name; also the key_id it signs with
  sdk::Role role = sdk::Role::User;  // what a message signed by it may do
  std::shared_ptr<const Ed25519Key> key;
};

struct MessageAuthSettings {
  bool require_signatures = false;
  std::vector<PeerKey> peers;
  double replay_window_s = kDefaultReplayWindowS;
  double future_skew_s = kDefaultFutureSkewS;
};

// The bytes a signature covers: the message as JSON with header.signature and the hop marker (kRelayMarker) removed, dumped by
// nlohmann (keys sorted, compact) - canonical whatever order the sender wrote.
std::string signing_input(const nlohmann::json& message);
// Adds header.signature {"key_id", "sig" (standard base64)} to `message` (a whole message object).
void sign_message(nlohmann::json& message, const std::string& key_id, const Ed25519Key& key);
// Adds header.auth.token.
void add_token(nlohmann::json& message, const std::string& token);

struct AuthFailure {
  std::string message;  // safe to send back in the 103 error and to log
};

class MessageAuthenticator {
 public:
  MessageAuthenticator(const Authenticator& tokens, MessageAuthSettings settings);

  // The principal of a parsed message, checked for `needed`. Order: a signature when present (must verify; it names
  // the principal), else required signatures -> failure, else header.auth.token, else the transport's principal.
  // `raw` is the message as received (for the signature input); now_s = wall clock, Unix seconds.
  std::variant<Principal, AuthFailure> authorize(const Envelope& envelope, const nlohmann::json& raw,
                                                 const std::optional<Principal>& transport_principal, sdk::Scope needed,
                                                 double now_s) const;
  const MessageAuthSettings& settings() const noexcept { return settings_; }
  // A SIGHUP reload (runtime.r2r.peers_file): from now on signatures are checked against `peers`, all at once.
  void replace_peers(std::vector<PeerKey> peers);
  std::size_t peer_count() const;

 private:
  std::variant<Principal, AuthFailure> verify_signature(const Envelope& envelope, const nlohmann::json& raw, double now_s) const;
  std::shared_ptr<const std::vector<PeerKey>> current_peers() const;
  const Authenticator& tokens_;
  MessageAuthSettings settings_;  // its peers as at start; peers_ is the table in force
  mutable std::mutex peers_mutex_;
  std::shared_ptr<const std::vector<PeerKey>> peers_;
};

// The scope a message type needs from its sender: status/error need `status`, the rest `control`.
sdk::Scope required_scope(MessageType type) noexcept;

}  // namespace rcand::kernel::r2r
