// Deny-by-default request authorization (docs/protocol.md §3): pre-shared tokens (stored as SHA-256 hashes) and HS256 JWTs.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "libs/rcan/ruri.hpp"
#include "rcand/sdk/scope.hpp"

namespace rcand::kernel {

struct PresharedToken {
  std::string principal;
  sdk::Role role;
  std::string sha256_hex;  // of the token; 64 hex digits (either case)
};

struct AuthSettings {
  bool open_mode = false;                 // explicit "no auth" (the kernel refuses it off loopback)
  std::optional<std::string> jwt_secret;  // HS256 secret bytes; nullopt = JWTs are not accepted
  std::vector<PresharedToken> tokens;
  std::string robot_ruri;  // for aud
  std::string device_id;   // for fleet
};

struct Principal {
  std::string name;
  sdk::Role role = sdk::Role::Guest;
  std::vector<sdk::Scope> scopes;
  std::string via;                                       // "token" | "jwt" | "open" | "anonymous"
  std::optional<std::int64_t> expires_s = std::nullopt;  // a JWT's exp (Unix s): what was authorized with it is void from then on
};

struct AuthError {
  int status = 401;
  std::string code = "UNAUTHORIZED";  // or "INSUFFICIENT_PRIVILEGES" with status 403
  std::string message;                // never contains the token or the secret
};

class Authenticator {
 public:
  // Throws std::invalid_argument naming the setting at fault: a stored hash that is not 64 hex digits, an empty JWT
  // secret, or (when a JWT secret is set) a robot_ruri that does not parse.
  explicit Authenticator(AuthSettings settings);

  // `bearer`: the credential without "Bearer " (nullopt when absent). Scope::None always passes (principal "anonymous").
  // Thread-safe and lock-free: the object is immutable after construction.
  std::variant<Principal, AuthError> authorize(std::optional<std::string_view> bearer, sdk::Scope needed,
                                               std::int64_t now_s) const;
  bool open_mode() const noexcept;
  // Config reload (SIGHUP): from now on every authorize() answers with `settings` (validated exactly as by the
  // constructor, which throws std::invalid_argument and leaves the current settings in force). Any thread.
  void replace(AuthSettings settings);
  // Bumped by every replace(): a holder of a long-lived authorization (an R2R WebSocket) re-authorizes when it moved.
  std::uint64_t generation() const noexcept { return generation_.load(std::memory_order_acquire); }

 private:
  std::variant<Principal, AuthError> authorize_jwt(std::string_view token, sdk::Scope needed, std::int64_t now_s) const;
  std::variant<Principal, AuthError> authorize_preshared(std::string_view token, sdk::Scope needed) const;

  AuthSettings settings_;
  std::optional<Ruri> robot_;  // settings_.robot_ruri, parsed once
  // The reloaded settings, when there was a reload; the flag keeps the common path to one relaxed load.
  std::atomic<bool> replaced_{false};
  std::atomic<std::shared_ptr<const Authenticator>> replacement_;
  std::atomic<std::uint64_t> generation_{0};
};

// Splits "Bearer <t>" (case-insensitive scheme); nullopt when absent or another scheme.
std::optional<std::string_view> bearer_token(std::string_view authorization_header);

}  // namespace rcand::kernel
