#include <doctest/doctest.h>

#include "jwt_helpers.hpp"
#include "libs/rcan/crypto.hpp"
#include "libs/rcan/jwt.hpp"

using namespace rcand;
using namespace auth_test;

namespace {
std::string failure(const std::variant<JwtClaims, JwtError>& result) {
  const auto* error = std::get_if<JwtError>(&result);
  return error ? error->message : std::string("<verified>");
}
}  // namespace

TEST_CASE("issue_jwt_hs256 writes a standard HS256 token that verify reads back") {
  JwtClaims claims;
  claims.sub = "bob";
  claims.iss = "rcanctl";
  claims.role = "USER";
  claims.aud = {"rcan://acme.rover.1a2b3c4d"};
  claims.scope = {"status", "control"};
  claims.iat = kNow;
  claims.exp = kNow + 60;
  claims.fleet = std::vector<std::string>{"1a2b3c4d", "deadbeef"};
  const std::string token = issue_jwt_hs256(claims, kSecret);
  CHECK(looks_like_jwt(token));

  const std::string header = *base64url_decode(token.substr(0, token.find('.')));
  CHECK(nlohmann::json::parse(header) == nlohmann::json({{"alg", "HS256"}, {"typ", "JWT"}}));
  const auto payload_part = token.substr(token.find('.') + 1, token.rfind('.') - token.find('.') - 1);
  const auto payload = nlohmann::json::parse(*base64url_decode(payload_part));
  CHECK(payload["aud"] == "rcan://acme.rover.1a2b3c4d");  // one audience is written as a string

  const auto result = verify_jwt_hs256(token, kSecret, kNow);
  REQUIRE(std::holds_alternative<JwtClaims>(result));
  const JwtClaims& read = std::get<JwtClaims>(result);
  CHECK(read.sub == "bob");
  CHECK(read.iss == "rcanctl");
  CHECK(read.role == "USER");
  CHECK(read.aud == claims.aud);
  CHECK(read.scope == claims.scope);
  CHECK(read.iat == kNow);
  CHECK(read.exp == kNow + 60);
  CHECK(read.fleet == claims.fleet);

  claims.aud = {"rcan://a.b.c", "rcan://d.e.f"};
  claims.fleet.reset();
  const auto two = verify_jwt_hs256(issue_jwt_hs256(claims, kSecret), kSecret, kNow);
  REQUIRE(std::holds_alternative<JwtClaims>(two));
  CHECK(std::get<JwtClaims>(two).aud == claims.aud);
  CHECK_FALSE(std::get<JwtClaims>(two).fleet);
}

TEST_CASE("verify_jwt_hs256 checks structure before anything else") {
  CHECK(failure(verify_jwt_hs256("a.b", kSecret, kNow)).find("three") != std::string::npos);
  CHECK(failure(verify_jwt_hs256("a.b.c.d", kSecret, kNow)).find("three") != std::string::npos);
  CHECK(failure(verify_jwt_hs256("!!.e30.x", kSecret, kNow)).find("header") != std::string::npos);
  CHECK(failure(verify_jwt_hs256(base64url_encode("[1]") + ".e30.", kSecret, kNow)).find("header") != std::string::npos);
  CHECK(failure(verify_jwt_hs256("e30." + base64url_encode("not json") + ".", kSecret, kNow)).find("payload") !=
        std::string::npos);
  CHECK(failure(verify_jwt_hs256(std::string(kJwtMaxLength + 1, 'a'), kSecret, kNow)).find("16 KiB") != std::string::npos);
}

TEST_CASE("alg none in any case and non-HS256 algorithms are refused before the signature") {
  for (const char* alg : {"none", "None", "NONE", "nOnE"}) {
    CHECK(failure(verify_jwt_hs256(forge({{"alg", alg}}, good_payload(), "", false), kSecret, kNow)).find("none") !=
          std::string::npos);
    // Even "signed" with our secret, alg none is refused.
    CHECK(failure(verify_jwt_hs256(forge({{"alg", alg}}, good_payload()), kSecret, kNow)).find("none") !=
          std::string::npos);
  }
  for (const char* alg : {"HS512", "RS256", "hs256", "ES256", ""})
    CHECK(failure(verify_jwt_hs256(forge({{"alg", alg}}, good_payload()), kSecret, kNow)).find("only HS256") !=
          std::string::npos);
  CHECK(failure(verify_jwt_hs256(forge({{"typ", "JWT"}}, good_payload()), kSecret, kNow)).find("alg") !=
        std::string::npos);
  CHECK(failure(verify_jwt_hs256(forge({{"alg", 256}}, good_payload()), kSecret, kNow)).find("alg") != std::string::npos);
}
