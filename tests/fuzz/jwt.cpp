// libFuzzer target: arbitrary bearer credentials against an Authenticator with a JWT secret and a pre-shared token.
// The first byte picks the scope asked for; the rest is the credential. Invariants: an accepted credential is
// accepted again with the same principal and grants the scope; a verified JWT re-issued from its claims verifies
// to the same claims; an error is 401/403 with a code, and its message quotes neither the token nor the secret.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <variant>

#include "fuzz_check.hpp"
#include "kernel/auth/authenticator.hpp"
#include "libs/rcan/crypto.hpp"
#include "libs/rcan/jwt.hpp"

namespace {

using namespace rcand;
using namespace rcand::kernel;

constexpr std::string_view kSecret = "fuzz-jwt-secret-0123456789abcdef";
constexpr std::string_view kRobotRuri = "rcan://rcand.sim-rover.5f3c2a1b";
constexpr std::int64_t kNow = 1'800'000'000;  // fixed, so the checked-in seeds stay valid (they expire in 2100)
constexpr rcand::sdk::Scope kScopes[] = {rcand::sdk::Scope::None,    rcand::sdk::Scope::Status,
                                         rcand::sdk::Scope::Control, rcand::sdk::Scope::Config,
                                         rcand::sdk::Scope::Training, rcand::sdk::Scope::Admin};

const Authenticator& authenticator() {
  static const Authenticator instance([] {
    AuthSettings settings;
    settings.jwt_secret = std::string(kSecret);
    settings.robot_ruri = std::string(kRobotRuri);
    settings.tokens.push_back({"fuzz-owner", rcand::sdk::Role::Owner, sha256_hex("fuzz-owner-token")});
    return settings;
  }());
  return instance;
}

bool same_claims(const JwtClaims& a, const JwtClaims& b) {
  return a.sub == b.sub && a.iss == b.iss && a.role == b.role && a.aud == b.aud && a.scope == b.scope &&
         a.iat == b.iat && a.exp == b.exp && a.fleet == b.fleet;
}

// `explain` gives the error message for a credential. A message containing the token may do so by coincidence (a
// token made of the message's own words): it quotes the token only if it also contains a token extended by a suffix.
template <typename Explain>
void check_never_quoted(const std::string& message, std::string_view token, Explain explain) {
  RCAND_FUZZ_CHECK(message.find(kSecret) == std::string::npos, "an auth error quotes the secret");
  if (token.size() < 8 || message.find(token) == std::string::npos) return;
  const std::string extended = std::string(token) + "Zq9";
  RCAND_FUZZ_CHECK(explain(extended).find(extended) == std::string::npos, "an auth error quotes the token");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const auto scope = kScopes[data[0] % std::size(kScopes)];
  const std::string_view token(reinterpret_cast<const char*>(data) + 1, size - 1);

  const auto result = authenticator().authorize(token, scope, kNow);
  if (const auto* principal = std::get_if<Principal>(&result)) {
    RCAND_FUZZ_CHECK(!principal->name.empty(), "an accepted credential names a principal");
    RCAND_FUZZ_CHECK(scope == rcand::sdk::Scope::None || rcand::sdk::role_grants(principal->role, scope),
                     "an accepted credential's role grants the scope");
    const auto again = authenticator().authorize(token, scope, kNow);
    const auto* second = std::get_if<Principal>(&again);
    RCAND_FUZZ_CHECK(second && second->name == principal->name && second->role == principal->role,
                     "an accepted credential is accepted again, as the same principal");
  } else {
    const auto& error = std::get<AuthError>(result);
    RCAND_FUZZ_CHECK((error.status == 401 && error.code == "UNAUTHORIZED") ||
                         (error.status == 403 && error.code == "INSUFFICIENT_PRIVILEGES"),
                     "an auth error is 401 UNAUTHORIZED or 403 INSUFFICIENT_PRIVILEGES");
    RCAND_FUZZ_CHECK(!error.message.empty(), "an auth error explains itself");
    check_never_quoted(error.message, token, [scope](const std::string& other) {
      const auto result = authenticator().authorize(other, scope, kNow);
      const auto* error = std::get_if<AuthError>(&result);
      return error ? error->message : std::string();
    });
  }

  const auto verified = verify_jwt_hs256(token, kSecret, kNow);
  if (const auto* claims = std::get_if<JwtClaims>(&verified)) {
    RCAND_FUZZ_CHECK(looks_like_jwt(token), "a verified JWT looks like one");
    const auto reissued = verify_jwt_hs256(issue_jwt_hs256(*claims, kSecret), kSecret, kNow);
    const auto* round_trip = std::get_if<JwtClaims>(&reissued);
    RCAND_FUZZ_CHECK(round_trip && same_claims(*claims, *round_trip), "verified claims re-issue to the same claims");
  } else {
    check_never_quoted(std::get<JwtError>(verified).message, token, [](const std::string& other) {
      const auto result = verify_jwt_hs256(other, kSecret, kNow);
      const auto* error = std::get_if<JwtError>(&result);
      return error ? error->message : std::string();
    });
  }
  return 0;
}
