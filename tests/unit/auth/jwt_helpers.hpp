// Builds tokens by hand so tests can forge every malformed, unsigned or mis-signed variant.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "libs/rcan/crypto.hpp"

namespace auth_test {

inline constexpr std::int64_t kNow = 1'700'000'000;
inline const std::string kSecret = "test-secret-\x01\x02-bytes";
inline const std::string kRobotRuri = "rcan://acme.rover.1a2b3c4d";
inline const std::string kDeviceId = "1a2b3c4d";

inline nlohmann::json good_payload(const std::string& role = "OWNER") {
  return {{"sub", "alice"},    {"iss", "test"},      {"aud", "rcan://*"},      {"role", role},
          {"scope", {"status", "control", "config"}}, {"iat", kNow - 10}, {"exp", kNow + 3600}};
}

// header.payload.signature with an HS256 signature over the encoded parts (signature_key empty = empty signature).
inline std::string forge(const nlohmann::json& header, const nlohmann::json& payload, const std::string& key = kSecret,
                         bool sign = true) {
  using rcand::base64url_encode;
  const std::string input = base64url_encode(header.dump()) + "." + base64url_encode(payload.dump());
  return input + "." + (sign ? base64url_encode(rcand::hmac_sha256(key, input)) : std::string());
}

inline std::string forge(const nlohmann::json& payload) { return forge({{"alg", "HS256"}, {"typ", "JWT"}}, payload); }

}  // namespace auth_test
