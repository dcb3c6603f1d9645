// Thin wrappers over OpenSSL (EVP, HMAC, RAND): the only place auth code touches crypto primitives.
// Every function is thread-safe and allocation-only; none of them logs what it is given.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <string_view>

namespace rcand {

// Lowercase hex of SHA-256(data): 64 characters.
std::string sha256_hex(std::string_view data);
// Raw 32-byte HMAC-SHA256 tag (RFC 2104 / RFC 4231).
std::string hmac_sha256(std::string_view key, std::string_view data);
// RFC 4648 §5 alphabet, without '=' padding (the JWT encoding).
std::string base64url_encode(std::string_view data);
// Strict inverse of base64url_encode: rejects padding, whitespace, the '+' '/' alphabet, impossible lengths and
// non-canonical trailing bits (so one byte string has exactly one accepted encoding).
std::optional<std::string> base64url_decode(std::string_view text);
// Compares in time that depends only on the lengths (CRYPTO_memcmp), for secrets and MACs.
bool constant_time_equals(std::string_view a, std::string_view b) noexcept;
// `bytes` bytes from RAND_bytes, as 2*bytes lowercase hex. Throws std::runtime_error when the CSPRNG fails.
std::string random_hex(std::size_t bytes);

}  // namespace rcand
