#include "command_input.hpp"
#include "trimmed.hpp"

namespace rcand::plugins::chat {
namespace {

using sdk::Json;
using sdk::Response;

// Code points in UTF-8 text (the JSON parser already refused invalid UTF-8).
std::size_t code_points(const std::string& s) {
  std::size_t n = 0;
  for (unsigned char c : s) n += (c & 0xC0) != 0x80;
  return n;
}

// C0 controls other than tab and newlines, DEL, C1 controls (U+0080..U+009F) and the bidirectional overrides and
// isolates (U+202A..U+202E, U+2066..U+2069).
bool has_controls(const std::string& s) {
  for (std::size_t i = 0; i < s.size(); ++i) {
    const auto c = static_cast<unsigned char>(s[i]);
    if ((c < 0x20 && c != '\t' && c != '\n' && c != '\r') || c == 0x7F) return true;
    if (c == 0xC2 && i + 1 < s.size() && static_cast<unsigned char>(s[i + 1]) >= 0x80 &&
        static_cast<unsigned char>(s[i + 1]) <= 0x9F)
      return true;
    if (c == 0xE2 && i + 2 < s.size()) {
      const auto b1 = static_cast<unsigned char>(s[i + 1]), b2 = static_cast<unsigned char>(s[i + 2]);
      if ((b1 == 0x80 && b2 >= 0xAA && b2 <= 0xAE) || (b1 == 0x81 && b2 >= 0xA6 && b2 <= 0xA9)) return true;
    }
  }
  return false;
}

bool is_base64(const std::string& s) {
  std::size_t padding = 0;
  for (char c : s) {
    const bool alnum = (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9');
    if (c == '=') {
      ++padding;
      continue;
    }
    if (padding > 0 || !(alnum || c == '+' || c == '/' || c == '-' || c == '_')) return false;
  }
  return padding <= 2;
}

}  // namespace

std::variant<CommandInput, sdk::Response> read_command(const Json& body, std::size_t max_chars, std::size_t max_image_bytes) {
  if (!body.is_object())
    return Response::bad_request("body", "the body must be a JSON object: {\"instruction\": \"...\", \"image_b64\"?: \"...\"}");
  const auto it = body.find("instruction");
  if (it == body.end() || it->is_null()) return Response::bad_request("instruction", "instruction is required: a string");
  if (!it->is_string())
    return Response::bad_request("instruction", std::string("instruction must be a string, found ") + it->type_name());
  CommandInput input;
  const std::string& raw = it->get_ref<const std::string&>();
  if (code_points(raw) > max_chars)
    return Response::error(
        413, "PAYLOAD_TOO_LARGE",
        "instruction is " + std::to_string(code_points(raw)) + " characters, over the limit of " + std::to_string(max_chars),
        Json{{"field", "instruction"}, {"limit", max_chars}});
  if (has_controls(raw))
    return Response::bad_request("instruction", "instruction contains control or direction-override characters (binary data?)");
  input.instruction = trimmed(raw);
  if (input.instruction.empty()) return Response::bad_request("instruction", "instruction must not be empty");

  if (const auto image = body.find("image_b64"); image != body.end() && !image->is_null()) {
    if (!image->is_string())
      return Response::bad_request("image_b64", std::string("image_b64 must be a base64 string, found ") + image->type_name());
    std::string data = image->get<std::string>();
    if (data.size() > max_image_bytes)
      return Response::error(413, "PAYLOAD_TOO_LARGE",
                             "image_b64 is over the limit of " + std::to_string(max_image_bytes) + " bytes",
                             Json{{"field", "image_b64"}, {"limit", max_image_bytes}});
    if (data.rfind("data:", 0) == 0) {  // a data URI: data:image/jpeg;base64,...
      const auto comma = data.find(',');
      if (comma == std::string::npos || data.substr(0, comma).find(";base64") == std::string::npos)
        return Response::bad_request("image_b64", "image_b64 must be base64 (or a base64 data: URI)");
      data.erase(0, comma + 1);
    }
    if (data.empty() || !is_base64(data))
      return Response::bad_request("image_b64", "image_b64 must be base64 (or a base64 data: URI)");
    input.image_b64 = std::move(data);
  }
  return input;
}

}  // namespace rcand::plugins::chat
