#include "libs/rcan/machine_identity.hpp"

#include <algorithm>
#include <cctype>
#include <fstream>

#include "libs/rcan/crypto.hpp"

namespace rcand {

std::optional<std::string> robot_uuid_from_machine_id(const std::filesystem::path& machine_id_file) {
  std::ifstream in(machine_id_file);
  std::string id;
  if (!(in >> id) || id.size() != 32 || !std::all_of(id.begin(), id.end(), [](unsigned char c) { return std::isxdigit(c); }))
    return std::nullopt;
  std::string bytes = hmac_sha256(id, "rcand robot identity").substr(0, 16);  // the application-specific id
  bytes[6] = static_cast<char>((bytes[6] & 0x0f) | 0x40);                     // version 4 shape
  bytes[8] = static_cast<char>((bytes[8] & 0x3f) | 0x80);                     // RFC 4122 variant
  std::string hex;
  for (const unsigned char byte : bytes) {
    hex += "0123456789abcdef"[byte >> 4];
    hex += "0123456789abcdef"[byte & 0x0f];
  }
  return hex.substr(0, 8) + "-" + hex.substr(8, 4) + "-" + hex.substr(12, 4) + "-" + hex.substr(16, 4) + "-" + hex.substr(20);
}

bool is_placeholder_uuid(std::string_view uuid) noexcept {
  return uuid == "00000000-0000-0000-0000-000000000000" || uuid == "00000000-0000-4000-8000-000000000000";
}

}  // namespace rcand
