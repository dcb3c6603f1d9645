#include "libs/rcan/jwt.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>

#include <nlohmann/json.hpp>

#include "libs/rcan/crypto.hpp"

namespace rcand {
namespace {

using nlohmann::json;

JwtError error(std::string message) { return JwtError{std::move(message)}; }

bool iequals(std::string_view a, std::string_view b) {
  return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) {
           return std::tolower(static_cast<unsigned char>(x)) == std::tolower(static_cast<unsigned char>(y));
         });
}

// Decodes one part into a JSON object; nullopt when it is not base64url or not a JSON object.
std::optional<json> decode_object(std::string_view part) {
  const std::optional<std::string> raw = base64url_decode(part);
  if (!raw) return std::nullopt;
  json value = json::parse(*raw, nullptr, /*allow_exceptions=*/false);
  if (!value.is_object()) return std::nullopt;
  return value;
}

// NumericDate (RFC 7519 §2): an integer or a finite number of seconds, within int64 range.
std::optional<std::int64_t> numeric_date(const json& value) {
  if (value.is_number_unsigned()) {
    const auto v = value.get<std::uint64_t>();
    if (v > static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max())) return std::nullopt;
    return static_cast<std::int64_t>(v);
  }
  if (value.is_number_integer()) return value.get<std::int64_t>();
  if (value.is_number_float()) {
    const double v = value.get<double>();
    if (!std::isfinite(v) || std::fabs(v) > 9.0e15) return std::nullopt;
    return static_cast<std::int64_t>(std::floor(v));
  }
  return std::nullopt;
}

// A string, or (when allow_string is false) only an array, of strings.
std::optional<std::vector<std::string>> string_list(const json& value, bool allow_string) {
  if (allow_string && value.is_string()) return std::vector<std::string>{value.get<std::string>()};
  if (!value.is_array()) return std::nullopt;
  std::vector<std::string> out;
  for (const json& item : value) {
    if (!item.is_string()) return std::nullopt;
    out.push_back(item.get<std::string>());
  }
  return out;
}

}  // namespace

std::string issue_jwt_hs256(const JwtClaims& claims, std::string_view secret) {
  const json header = {{"alg", "HS256"}, {"typ", "JWT"}};
  json payload = {{"sub", claims.sub},     {"iss", claims.iss}, {"role", claims.role},
                  {"scope", claims.scope}, {"iat", claims.iat}, {"exp", claims.exp}};
  payload["aud"] = claims.aud.size() == 1 ? json(claims.aud.front()) : json(claims.aud);
  if (claims.fleet) payload["fleet"] = *claims.fleet;
  const std::string signing_input = base64url_encode(header.dump()) + "." + base64url_encode(payload.dump());
  return signing_input + "." + base64url_encode(hmac_sha256(secret, signing_input));
}

bool looks_like_jwt(std::string_view token) noexcept {
  if (std::count(token.begin(), token.end(), '.') != 2) return false;
  return std::all_of(token.begin(), token.end(),
                     [](char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' || c == '.'; });
}

std::variant<JwtClaims, JwtError> verify_jwt_hs256(std::string_view token, std::string_view secret, std::int64_t now_s) {
  // 1. Structure.
  if (token.size() > kJwtMaxLength) return error("malformed JWT: longer than 16 KiB");
  const std::size_t dot1 = token.find('.');
  const std::size_t dot2 = dot1 == std::string_view::npos ? dot1 : token.find('.', dot1 + 1);
  if (dot2 == std::string_view::npos || token.find('.', dot2 + 1) != std::string_view::npos)
    return error("malformed JWT: expected three base64url parts separated by dots");
  const std::string_view header_part = token.substr(0, dot1);
  const std::string_view payload_part = token.substr(dot1 + 1, dot2 - dot1 - 1);
  const std::string_view signature_part = token.substr(dot2 + 1);
  const std::optional<json> header = decode_object(header_part);
  if (!header) return error("malformed JWT: the header is not a base64url-encoded JSON object");
  const std::optional<json> payload = decode_object(payload_part);
  if (!payload) return error("malformed JWT: the payload is not a base64url-encoded JSON object");
  const std::optional<std::string> signature = base64url_decode(signature_part);
  if (!signature) return error("malformed JWT: the signature is not base64url");

  // 2. Algorithm: never let the token choose a weaker check than the one we configured.
  const auto alg = header->find("alg");
  if (alg == header->end() || !alg->is_string()) return error("JWT header has no 'alg' string");
  const std::string& alg_name = alg->get_ref<const std::string&>();
  if (iequals(alg_name, "none")) return error("JWT alg 'none' is never accepted");
  if (alg_name != "HS256") return error("JWT alg is not supported: only HS256 is accepted");

  // 3. Signature over the encoded header and payload exactly as sent.
  const std::string expected = hmac_sha256(secret, token.substr(0, dot2));
  if (!constant_time_equals(expected, *signature)) return error("JWT signature is invalid");

  // 4. Times (presence and type first: a token without exp must not read as "never expires").
  const auto exp_it = payload->find("exp");
  if (exp_it == payload->end()) return error("JWT is missing required claim 'exp'");
  const std::optional<std::int64_t> exp = numeric_date(*exp_it);
  if (!exp) return error("JWT claim 'exp' must be a number of seconds since the epoch");
  const auto iat_it = payload->find("iat");
  if (iat_it == payload->end()) return error("JWT is missing required claim 'iat'");
  const std::optional<std::int64_t> iat = numeric_date(*iat_it);
  if (!iat) return error("JWT claim 'iat' must be a number of seconds since the epoch");
  if (*exp < now_s - kJwtExpLeewayS) return error("JWT has expired (exp is in the past)");
  if (*iat > now_s + kJwtIatLeewayS) return error("JWT is issued in the future (iat is ahead of this robot's clock)");

  // 5. Required claims and their types.
  JwtClaims claims;
  claims.exp = *exp;
  claims.iat = *iat;
  for (const char* name : {"sub", "iss", "aud", "role", "scope"})
    if (!payload->contains(name)) return error(std::string("JWT is missing required claim '") + name + "'");
  const auto string_claim = [&](const char* name, std::string& out) -> std::optional<JwtError> {
    const json& value = payload->at(name);
    if (!value.is_string()) return error(std::string("JWT claim '") + name + "' must be a string");
    out = value.get<std::string>();
    return std::nullopt;
  };
  if (auto e = string_claim("sub", claims.sub)) return *e;
  if (auto e = string_claim("iss", claims.iss)) return *e;
  if (auto e = string_claim("role", claims.role)) return *e;
  std::optional<std::vector<std::string>> aud = string_list(payload->at("aud"), /*allow_string=*/true);
  if (!aud || aud->empty()) return error("JWT claim 'aud' must be a RURI string or a non-empty array of them");
  claims.aud = std::move(*aud);
  std::optional<std::vector<std::string>> scope = string_list(payload->at("scope"), /*allow_string=*/false);
  if (!scope) return error("JWT claim 'scope' must be an array of strings");
  claims.scope = std::move(*scope);
  if (const auto fleet = payload->find("fleet"); fleet != payload->end()) {
    claims.fleet = string_list(*fleet, /*allow_string=*/false);
    if (!claims.fleet) return error("JWT claim 'fleet' must be an array of device ids");
  }
  return claims;
}

}  // namespace rcand
