#include "kernel/auth/authenticator.hpp"

#include <algorithm>
#include <cctype>
#include <cstdint>
#include <limits>
#include <stdexcept>

#include "libs/rcan/crypto.hpp"
#include "libs/rcan/jwt.hpp"
#include "libs/rcan/role_scopes.hpp"

namespace rcand::kernel {
namespace {

AuthError unauthorized(std::string message) { return AuthError{401, "UNAUTHORIZED", std::move(message)}; }
AuthError forbidden(std::string message) { return AuthError{403, "INSUFFICIENT_PRIVILEGES", std::move(message)}; }

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

std::string role_too_low(sdk::Role role, sdk::Scope needed) {
  return "role " + std::string(sdk::role_name(role)) + " cannot use scope '" + std::string(sdk::scope_name(needed)) +
         "': it needs " + std::string(sdk::role_name(sdk::minimum_role(needed))) + " or higher";
}

}  // namespace

Authenticator::Authenticator(AuthSettings settings) : settings_(std::move(settings)) {
  for (PresharedToken& token : settings_.tokens) {
    token.sha256_hex = lower(token.sha256_hex);
    if (token.sha256_hex.size() != 64 || !std::all_of(token.sha256_hex.begin(), token.sha256_hex.end(),
                                                      [](char c) { return std::isxdigit(static_cast<unsigned char>(c)); }))
      throw std::invalid_argument("auth: the sha256 of the token for principal '" + token.principal +
                                  "' must be 64 hex digits (make one with `rcanctl token hash`)");
  }
  if (settings_.jwt_secret) {
    if (settings_.jwt_secret->empty()) throw std::invalid_argument("auth: the JWT secret is empty");
    const RuriParse parsed = parse_ruri(settings_.robot_ruri);
    if (!parsed.ruri) throw std::invalid_argument("auth: the robot RURI is needed to check JWT aud: " + parsed.error);
    robot_ = parsed.ruri;
  }
}

bool Authenticator::open_mode() const noexcept {
  if (replaced_.load(std::memory_order_acquire)) return replacement_.load()->open_mode();
  return settings_.open_mode;
}

void Authenticator::replace(AuthSettings settings) {
  replacement_.store(std::make_shared<const Authenticator>(std::move(settings)));
  replaced_.store(true, std::memory_order_release);
  generation_.fetch_add(1, std::memory_order_acq_rel);
}

std::variant<Principal, AuthError> Authenticator::authorize(std::optional<std::string_view> bearer, sdk::Scope needed,
                                                            std::int64_t now_s) const {
  if (replaced_.load(std::memory_order_acquire)) return replacement_.load()->authorize(bearer, needed, now_s);
  if (needed == sdk::Scope::None) return Principal{"anonymous", sdk::Role::Guest, {}, "anonymous"};
  if (settings_.open_mode) return Principal{"open", sdk::Role::Creator, default_scopes(sdk::Role::Creator), "open"};
  if (!bearer || bearer->empty()) return unauthorized("authentication required: send 'Authorization: Bearer <token>'");
  if (looks_like_jwt(*bearer)) return authorize_jwt(*bearer, needed, now_s);
  return authorize_preshared(*bearer, needed);
}

std::variant<Principal, AuthError> Authenticator::authorize_jwt(std::string_view token, sdk::Scope needed,
                                                                std::int64_t now_s) const {
  if (!settings_.jwt_secret || !robot_) return unauthorized("JWT authentication is not enabled on this robot");
  std::variant<JwtClaims, JwtError> verified = verify_jwt_hs256(token, *settings_.jwt_secret, now_s);
  if (auto* failure = std::get_if<JwtError>(&verified)) return unauthorized(std::move(failure->message));
  const JwtClaims& claims = std::get<JwtClaims>(verified);

  const bool aud_ok = std::any_of(claims.aud.begin(), claims.aud.end(), [&](const std::string& aud) {
    const RuriParse pattern = parse_ruri(aud, /*allow_wildcards=*/true);
    return pattern.ruri && ruri_matches(*pattern.ruri, *robot_);
  });
  if (!aud_ok) return unauthorized("JWT audience (aud) does not match this robot's RURI " + settings_.robot_ruri);

  const std::optional<sdk::Role> role = sdk::parse_role(claims.role);
  if (!role) return unauthorized("JWT claim 'role' is not a known role (CREATOR, OWNER, LEASEE, USER, GUEST)");
  if (!sdk::role_grants(*role, needed)) return forbidden(role_too_low(*role, needed));

  std::vector<sdk::Scope> scopes = granted_scopes(*role, claims.scope);  // claim ∩ role, for every transport
  if (std::find(scopes.begin(), scopes.end(), needed) == scopes.end())
    return forbidden("JWT scope[] does not include '" + std::string(sdk::scope_name(needed)) + "'");

  if (claims.fleet && std::find(claims.fleet->begin(), claims.fleet->end(), settings_.device_id) == claims.fleet->end())
    return unauthorized("JWT fleet does not include this robot's device id");

  // Good until exp plus the leeway the check above allows (saturating: exp may be any int64).
  const std::int64_t expires_s = claims.exp > std::numeric_limits<std::int64_t>::max() - kJwtExpLeewayS
                                     ? std::numeric_limits<std::int64_t>::max()
                                     : claims.exp + kJwtExpLeewayS;
  return Principal{claims.sub, *role, std::move(scopes), "jwt", expires_s};
}

std::variant<Principal, AuthError> Authenticator::authorize_preshared(std::string_view token, sdk::Scope needed) const {
  const std::string hash = sha256_hex(token);
  const PresharedToken* match = nullptr;
  for (const PresharedToken& candidate : settings_.tokens)  // no early exit: the time does not depend on which one
    if (constant_time_equals(hash, candidate.sha256_hex) && match == nullptr) match = &candidate;
  if (match == nullptr) return unauthorized("unknown or invalid token");
  if (!sdk::role_grants(match->role, needed)) return forbidden(role_too_low(match->role, needed));
  return Principal{match->principal, match->role, default_scopes(match->role), "token"};
}

std::optional<std::string_view> bearer_token(std::string_view header) {
  const auto is_space = [](char c) { return c == ' ' || c == '\t'; };
  while (!header.empty() && is_space(header.front())) header.remove_prefix(1);
  while (!header.empty() && is_space(header.back())) header.remove_suffix(1);
  constexpr std::string_view kScheme = "bearer";
  if (header.size() <= kScheme.size() || !is_space(header[kScheme.size()])) return std::nullopt;
  for (std::size_t i = 0; i < kScheme.size(); ++i)
    if (std::tolower(static_cast<unsigned char>(header[i])) != kScheme[i]) return std::nullopt;
  header.remove_prefix(kScheme.size());
  while (!header.empty() && is_space(header.front())) header.remove_prefix(1);
  if (header.empty()) return std::nullopt;
  return header;
}

}  // namespace rcand::kernel
