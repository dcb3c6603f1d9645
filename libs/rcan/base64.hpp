// Standard base64 (RFC 4648 §4, with padding) for R2R signatures and raw keys, over OpenSSL's EVP encoder.
#pragma once

#include <optional>
#include <string>
#include <string_view>

namespace rcand {

std::string base64_encode(std::string_view data);
// Strict: padded, no whitespace, only the standard alphabet, and canonical (the unused bits of the last symbol zero:
// the text is exactly base64_encode of the result); nullopt otherwise.
std::optional<std::string> base64_decode(std::string_view text);

}  // namespace rcand
