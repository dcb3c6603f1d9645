// HS256 JSON Web Tokens (RFC 7519) with the RCAN claims (docs/protocol.md §3). Issuing is here; verification of the structure,
// algorithm, signature, times and claim types is here too, while the robot-specific checks (aud, role, scope, fleet)
// live in Authenticator.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

namespace rcand {

struct JwtClaims {
  std::string sub, iss, role;
  std::vector<std::string> aud;  // "aud" may be a string or an array in the token
  std::vector<std::string> scope;
  std::int64_t iat = 0, exp = 0;
  std::optional<std::vector<std::string>> fleet;
};

inline constexpr std::int64_t kJwtExpLeewayS = 30;  // a token is still good this long after exp (clock skew)
inline constexpr std::int64_t kJwtIatLeewayS = 60;  // iat may be this far in the future (clock skew)
inline constexpr std::size_t kJwtMaxLength = 16 * 1024;

// "aud" is written as a string when it has one entry, else as an array; "fleet" only when set.
std::string issue_jwt_hs256(const JwtClaims& claims, std::string_view secret);

// Three non-empty-ish base64url parts separated by exactly two dots. Anything else is treated as a pre-shared token.
bool looks_like_jwt(std::string_view token) noexcept;

// The message never contains the token or the secret.
struct JwtError {
  std::string message;
};

// Verifies, in this order: structure (3 base64url parts, JSON object header and payload), header alg ("none" in any
// case always rejected, only "HS256" accepted), signature (constant time), exp (kJwtExpLeewayS) and iat
// (kJwtIatLeewayS), then that sub, iss, aud, role, scope are present with the right types (and fleet when present).
std::variant<JwtClaims, JwtError> verify_jwt_hs256(std::string_view token, std::string_view secret, std::int64_t now_s);

}  // namespace rcand
