// The body of POST /api/command, checked on the capability's worker before anything is queued: {"instruction":
// "...", "image_b64"?: "..."}. Every refusal names the field: a missing, non-string or empty instruction (400), one
// over the length limit (413 PAYLOAD_TOO_LARGE), control characters or invisible direction overrides - binary data,
// or text built to read differently than it shows (400); an image that is not base64 or is too large (400 / 413).
// Other fields are ignored (§9 swarm fields among them).
#pragma once

#include <rcand/sdk/http.hpp>

#include <string>
#include <variant>

namespace rcand::plugins::chat {

struct CommandInput {
  std::string instruction;  // trimmed
  std::string image_b64;    // "" when none; a data: URI prefix removed
};

std::variant<CommandInput, sdk::Response> read_command(const sdk::Json& body, std::size_t max_chars, std::size_t max_image_bytes);

}  // namespace rcand::plugins::chat
