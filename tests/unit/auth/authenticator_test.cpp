#include <doctest/doctest.h>

#include <cstdint>
#include <limits>
#include <stdexcept>

#include "jwt_helpers.hpp"
#include "kernel/auth/authenticator.hpp"
#include "libs/rcan/crypto.hpp"
#include "libs/rcan/jwt.hpp"
#include "libs/rcan/role_scopes.hpp"

using namespace rcand;
using namespace rcand::kernel;
using namespace auth_test;
using rcand::sdk::Role;
using rcand::sdk::Scope;

namespace {

const std::string kOwnerToken = "owner-preshared-token-0123456789";
const std::string kGuestToken = "guest-preshared-token-0123456789";

AuthSettings settings(bool with_secret = true) {
  AuthSettings s;
  if (with_secret) s.jwt_secret = kSecret;
  s.tokens = {{"swarm-peer", Role::Owner, sha256_hex(kOwnerToken)}, {"viewer", Role::Guest, sha256_hex(kGuestToken)}};
  s.robot_ruri = kRobotRuri;
  s.device_id = kDeviceId;
  return s;
}

Principal allowed(const std::variant<Principal, AuthError>& result) {
  if (const auto* error = std::get_if<AuthError>(&result)) FAIL("expected success, got ", error->status, " ", error->message);
  return std::get<Principal>(result);
}

// Checks the status and code, that the message says `mentions`, and that it never echoes the credential.
void denied(const std::variant<Principal, AuthError>& result, int status, std::string_view mentions,
            std::string_view credential = {}) {
  REQUIRE(std::holds_alternative<AuthError>(result));
  const AuthError& error = std::get<AuthError>(result);
  INFO("message: ", error.message);
  CHECK(error.status == status);
  CHECK(error.code == (status == 403 ? "INSUFFICIENT_PRIVILEGES" : "UNAUTHORIZED"));
  CHECK(error.message.find(mentions) != std::string::npos);
  if (!credential.empty()) CHECK(error.message.find(credential) == std::string::npos);
  CHECK(error.message.find(kSecret) == std::string::npos);
}

}  // namespace

TEST_CASE("a valid JWT authorizes with its sub, role and scopes") {
  const Authenticator auth(settings());
  const Principal p = allowed(auth.authorize(forge(good_payload()), Scope::Config, kNow));
  CHECK(p.name == "alice");
  CHECK(p.role == Role::Owner);
  CHECK(p.via == "jwt");
  CHECK(p.scopes == std::vector<Scope>{Scope::Status, Scope::Control, Scope::Config});
  CHECK_FALSE(auth.open_mode());
}

TEST_CASE("missing and garbage credentials are 401") {
  const Authenticator auth(settings());
  denied(auth.authorize(std::nullopt, Scope::Status, kNow), 401, "Bearer");
  denied(auth.authorize("", Scope::Status, kNow), 401, "Bearer");
  denied(auth.authorize("garbage", Scope::Status, kNow), 401, "unknown", "garbage");
  denied(auth.authorize("not.a.jwt", Scope::Status, kNow), 401, "malformed JWT", "not.a.jwt");
  denied(auth.authorize("a.b.c.d", Scope::Status, kNow), 401, "unknown");  // four parts: not JWT-shaped
}

TEST_CASE("Scope::None always passes as anonymous, even with a bad token") {
  const Authenticator auth(settings());
  for (const std::optional<std::string_view> bearer : {std::optional<std::string_view>{}, std::optional<std::string_view>{"junk"}}) {
    const Principal p = allowed(auth.authorize(bearer, Scope::None, kNow));
    CHECK(p.name == "anonymous");
    CHECK(p.via == "anonymous");
    CHECK(p.scopes.empty());
  }
}

TEST_CASE("JWT signature, algorithm and time failures are 401 with distinct messages") {
  const Authenticator auth(settings());
  const std::string wrong_key = forge({{"alg", "HS256"}}, good_payload(), "another secret");
  denied(auth.authorize(wrong_key, Scope::Status, kNow), 401, "signature is invalid", wrong_key);

  std::string tampered = forge(good_payload("GUEST"));
  const std::string owner_payload = forge(good_payload("CREATOR"));
  // Swap in a CREATOR payload under the GUEST token's signature.
  tampered = tampered.substr(0, tampered.find('.')) + owner_payload.substr(owner_payload.find('.'), owner_payload.rfind('.') - owner_payload.find('.')) + tampered.substr(tampered.rfind('.'));
  denied(auth.authorize(tampered, Scope::Status, kNow), 401, "signature is invalid");
  const std::string unsigned_token = forge({{"alg", "HS256"}}, good_payload(), "", false);
  denied(auth.authorize(unsigned_token, Scope::Status, kNow), 401, "signature is invalid");

  denied(auth.authorize(forge({{"alg", "none"}}, good_payload(), "", false), Scope::Status, kNow), 401, "'none'");
  denied(auth.authorize(forge({{"alg", "None"}, {"typ", "JWT"}}, good_payload(), "", false), Scope::Status, kNow), 401,
         "'none'");
  denied(auth.authorize(forge({{"alg", "HS512"}}, good_payload()), Scope::Status, kNow), 401, "only HS256");
  denied(auth.authorize(forge({{"alg", "RS256"}}, good_payload()), Scope::Status, kNow), 401, "only HS256");

  auto expired = good_payload();
  expired["exp"] = kNow - kJwtExpLeewayS - 1;
  denied(auth.authorize(forge(expired), Scope::Status, kNow), 401, "expired");
  expired["exp"] = kNow - kJwtExpLeewayS;  // inside the leeway
  allowed(auth.authorize(forge(expired), Scope::Status, kNow));

  auto future = good_payload();
  future["iat"] = kNow + kJwtIatLeewayS + 1;
  denied(auth.authorize(forge(future), Scope::Status, kNow), 401, "future");
  future["iat"] = kNow + kJwtIatLeewayS;
  allowed(auth.authorize(forge(future), Scope::Status, kNow));
}

TEST_CASE("each missing or mistyped required claim is a 401 naming the claim") {
  const Authenticator auth(settings());
  for (const char* claim : {"sub", "iss", "aud", "role", "scope", "exp", "iat"}) {
    auto payload = good_payload();
    payload.erase(claim);
    denied(auth.authorize(forge(payload), Scope::Status, kNow), 401,
           std::string("missing required claim '") + claim + "'");
  }
  const std::pair<const char*, nlohmann::json> mistyped[] = {
      {"sub", 5}, {"iss", nullptr}, {"role", {"OWNER"}}, {"aud", 7}, {"aud", nlohmann::json::array()},
      {"aud", {"rcan://*", 3}}, {"scope", "status"}, {"scope", {"status", 1}}, {"exp", "tomorrow"},
      {"iat", true}, {"exp", 1e300}, {"fleet", "1a2b3c4d"}};
  for (const auto& [claim, value] : mistyped) {
    auto payload = good_payload();
    payload[claim] = value;
    denied(auth.authorize(forge(payload), Scope::Status, kNow), 401, std::string("claim '") + claim + "'");
  }
  auto unknown_role = good_payload("WIZARD");
  denied(auth.authorize(forge(unknown_role), Scope::Status, kNow), 401, "role");
}

TEST_CASE("aud must match the robot RURI, wildcards allowed") {
  const Authenticator auth(settings());
  auto payload = good_payload();
  for (const char* aud : {"rcan://*", "*", "rcan://acme.rover.1a2b3c4d", "rcan://acme.*.*",
                          "rcan://local.rcan/acme/rover/1a2b3c4d", "rcan://*/acme/*/*"}) {
    payload["aud"] = aud;
    INFO("aud: ", aud);
    allowed(auth.authorize(forge(payload), Scope::Status, kNow));
  }
  payload["aud"] = {"rcan://acme.rover.deadbeef", "rcan://acme.rover.1a2b3c4d"};  // any entry may match
  allowed(auth.authorize(forge(payload), Scope::Status, kNow));

  for (const char* aud : {"rcan://acme.rover.deadbeef", "rcan://other.*.*", "rcan://rcan.dev/acme/rover/1a2b3c4d",
                          "not a ruri", "rcan://acme.rover.1a2b3c4*"}) {
    payload["aud"] = aud;
    INFO("aud: ", aud);
    denied(auth.authorize(forge(payload), Scope::Status, kNow), 401, "audience");
  }
}

TEST_CASE("role level and scope[] decide 403 INSUFFICIENT_PRIVILEGES") {
  const Authenticator auth(settings());
  // USER cannot use config even when scope[] lists it.
  auto user = good_payload("USER");
  user["scope"] = {"status", "control", "config"};
  denied(auth.authorize(forge(user), Scope::Config, kNow), 403, "needs OWNER");
  allowed(auth.authorize(forge(user), Scope::Control, kNow));

  // OWNER with the right level but without 'control' in scope[].
  auto narrow = good_payload("OWNER");
  narrow["scope"] = {"status"};
  denied(auth.authorize(forge(narrow), Scope::Control, kNow), 403, "scope[] does not include 'control'");
  allowed(auth.authorize(forge(narrow), Scope::Status, kNow));

  // Unknown scope names are ignored; scope names are case-insensitive.
  narrow["scope"] = {"STATUS", "Control", "teleport"};
  const Principal p = allowed(auth.authorize(forge(narrow), Scope::Control, kNow));
  CHECK(p.scopes == std::vector<Scope>{Scope::Status, Scope::Control});

  auto guest = good_payload("guest");
  guest["scope"] = {"status", "control"};
  denied(auth.authorize(forge(guest), Scope::Control, kNow), 403, "GUEST");
  auto creator = good_payload("Creator");
  creator["scope"] = {"admin"};
  CHECK(allowed(auth.authorize(forge(creator), Scope::Admin, kNow)).role == Role::Creator);
}

TEST_CASE("the scopes granted are the claim intersected with the role's: a GUEST claiming control has status only") {
  const Authenticator auth(settings());
  auto guest = good_payload("GUEST");
  guest["scope"] = {"status", "control", "config", "admin"};
  // Authorized for status (what the /ws/r2r upgrade asks), the principal carries status alone: every later check
  // (each R2R message's scope) sees what the role allows, not what the token claims.
  const Principal p = allowed(auth.authorize(forge(guest), Scope::Status, kNow));
  CHECK(p.scopes == std::vector<Scope>{Scope::Status});
  auto user = good_payload("USER");
  user["scope"] = {"admin", "config", "control", "status"};
  CHECK(allowed(auth.authorize(forge(user), Scope::Status, kNow)).scopes == std::vector<Scope>{Scope::Status, Scope::Control});
  CHECK(granted_scopes(Role::User, {"training", "status", "nonsense"}) == std::vector<Scope>{Scope::Status});
  CHECK(granted_scopes(Role::Creator, {}).empty());
}

TEST_CASE("role names are case-insensitive") {
  const Authenticator auth(settings());
  for (const char* role : {"owner", "OWNER", "Owner", "oWnEr"})
    CHECK(allowed(auth.authorize(forge(good_payload(role)), Scope::Config, kNow)).role == Role::Owner);
}

TEST_CASE("fleet, when present, must contain the device id") {
  const Authenticator auth(settings());
  auto payload = good_payload();
  payload["fleet"] = {"deadbeef", "cafebabe"};
  denied(auth.authorize(forge(payload), Scope::Status, kNow), 401, "fleet");
  payload["fleet"] = {"deadbeef", kDeviceId};
  allowed(auth.authorize(forge(payload), Scope::Status, kNow));
  payload["fleet"] = nlohmann::json::array();
  denied(auth.authorize(forge(payload), Scope::Status, kNow), 401, "fleet");
}

TEST_CASE("a JWT when no secret is configured is 401") {
  const Authenticator auth(settings(/*with_secret=*/false));
  const std::string token = forge(good_payload());
  denied(auth.authorize(token, Scope::Status, kNow), 401, "not enabled", token);
  // Pre-shared tokens still work.
  CHECK(allowed(auth.authorize(kOwnerToken, Scope::Status, kNow)).via == "token");
}

TEST_CASE("pre-shared tokens: good, bad, insufficient role") {
  const Authenticator auth(settings());
  const Principal owner = allowed(auth.authorize(kOwnerToken, Scope::Config, kNow));
  CHECK(owner.name == "swarm-peer");
  CHECK(owner.role == Role::Owner);
  CHECK(owner.via == "token");
  CHECK(owner.scopes == std::vector<Scope>{Scope::Status, Scope::Control, Scope::Config, Scope::Training});

  denied(auth.authorize(kOwnerToken + "x", Scope::Status, kNow), 401, "unknown", kOwnerToken);
  denied(auth.authorize(kOwnerToken, Scope::Admin, kNow), 403, "needs CREATOR", kOwnerToken);

  CHECK(allowed(auth.authorize(kGuestToken, Scope::Status, kNow)).name == "viewer");
  denied(auth.authorize(kGuestToken, Scope::Control, kNow), 403, "GUEST", kGuestToken);
}

TEST_CASE("stored hashes are accepted in either case and validated") {
  AuthSettings s = settings();
  s.tokens = {{"upper", Role::User, sha256_hex(kOwnerToken)}};
  for (char& c : s.tokens[0].sha256_hex) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  const Authenticator auth(s);
  CHECK(allowed(auth.authorize(kOwnerToken, Scope::Control, kNow)).name == "upper");

  s.tokens = {{"short", Role::User, "abc"}};
  CHECK_THROWS_WITH_AS(Authenticator{s}, doctest::Contains("principal 'short'"), std::invalid_argument);
  s.tokens = {{"nothex", Role::User, std::string(64, 'g')}};
  CHECK_THROWS_AS(Authenticator{s}, std::invalid_argument);
}

TEST_CASE("bad settings are refused at construction") {
  AuthSettings s = settings();
  s.robot_ruri = "not a ruri";
  CHECK_THROWS_WITH_AS(Authenticator{s}, doctest::Contains("robot RURI"), std::invalid_argument);
  s = settings();
  s.jwt_secret = "";
  CHECK_THROWS_WITH_AS(Authenticator{s}, doctest::Contains("secret is empty"), std::invalid_argument);
  s = settings(/*with_secret=*/false);
  s.robot_ruri.clear();  // not needed without JWTs
  CHECK_NOTHROW(Authenticator{s});
}

TEST_CASE("open mode lets every request through, explicitly labelled") {
  AuthSettings s;
  s.open_mode = true;
  const Authenticator auth(s);
  CHECK(auth.open_mode());
  const Principal p = allowed(auth.authorize(std::nullopt, Scope::Admin, kNow));
  CHECK(p.via == "open");
  CHECK(p.role == Role::Creator);
  // Deny by default: the same settings without open_mode refuse.
  s.open_mode = false;
  denied(Authenticator(s).authorize(std::nullopt, Scope::Status, kNow), 401, "Bearer");
}

TEST_CASE("bearer_token splits the Authorization header") {
  CHECK(bearer_token("Bearer abc.def") == "abc.def");
  CHECK(bearer_token("bearer abc") == "abc");
  CHECK(bearer_token("BEARER   abc  ") == "abc");
  CHECK(bearer_token("  Bearer\tabc") == "abc");
  CHECK_FALSE(bearer_token(""));
  CHECK_FALSE(bearer_token("Bearer"));
  CHECK_FALSE(bearer_token("Bearer   "));
  CHECK_FALSE(bearer_token("Bearerabc"));
  CHECK_FALSE(bearer_token("Basic dXNlcjpwYXNz"));
  CHECK_FALSE(bearer_token("abc"));
}

TEST_CASE("any one-character change to a valid JWT is refused with 401") {
  const Authenticator auth(settings());
  const std::string token = forge(good_payload());
  REQUIRE(std::holds_alternative<Principal>(auth.authorize(token, Scope::Status, kNow)));
  const std::string alphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789-_.=+/ ";
  std::uint32_t seed = 12345;  // deterministic LCG: the same mutations on every run
  const auto next = [&seed] { return seed = seed * 1664525u + 1013904223u; };
  int tried = 0;
  for (std::size_t i = 0; i < token.size(); ++i) {
    std::string mutated = token;
    mutated[i] = alphabet[next() % alphabet.size()];
    if (mutated == token) continue;
    ++tried;
    const auto result = auth.authorize(mutated, Scope::Status, kNow);
    INFO("position ", i);
    REQUIRE(std::holds_alternative<AuthError>(result));
    CHECK(std::get<AuthError>(result).status == 401);
  }
  CHECK(tried > 100);
}

TEST_CASE("a JWT principal carries when it stops being good (exp + leeway), saturating for any int64 exp") {
  const Authenticator auth(settings());
  const Principal p = allowed(auth.authorize(forge(good_payload()), Scope::Status, kNow));
  REQUIRE(p.expires_s);
  CHECK(*p.expires_s == kNow + 3600 + kJwtExpLeewayS);  // an R2R socket opened with it is closed after this
  auto forever = good_payload();
  forever["exp"] = std::numeric_limits<std::int64_t>::max();  // was a signed overflow (UB) in exp + leeway
  CHECK(*allowed(auth.authorize(forge(forever), Scope::Status, kNow)).expires_s == std::numeric_limits<std::int64_t>::max());
  CHECK_FALSE(allowed(auth.authorize(kOwnerToken, Scope::Status, kNow)).expires_s);  // a token has no exp
}
