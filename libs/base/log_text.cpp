#include "libs/base/log_text.hpp"

#include <algorithm>

namespace rcand {
namespace {

constexpr std::size_t kCutMarkerRoom = 24;  // "...[+NNNNNNNNNN bytes]"

// The length of the UTF-8 sequence at text[i] and its code point, or 0 when the bytes there are not valid UTF-8
// (overlong forms, surrogates and values past U+10FFFF included).
std::size_t log_text_sequence(std::string_view text, std::size_t i, char32_t& code) {
  const auto lead = static_cast<unsigned char>(text[i]);
  const std::size_t length = lead < 0x80 ? 1 : (lead >> 5) == 0x6 ? 2 : (lead >> 4) == 0xE ? 3 : (lead >> 3) == 0x1E ? 4 : 0;
  if (length == 0 || i + length > text.size()) return 0;
  code = length == 1 ? lead : length == 2 ? lead & 0x1F : length == 3 ? lead & 0x0F : lead & 0x07;
  for (std::size_t k = 1; k < length; ++k) {
    const auto next = static_cast<unsigned char>(text[i + k]);
    if ((next & 0xC0) != 0x80) return 0;
    code = (code << 6) | (next & 0x3F);
  }
  const char32_t smallest = length == 1 ? 0 : length == 2 ? 0x80 : length == 3 ? 0x800 : 0x10000;
  if (code < smallest || code > 0x10FFFF || (code >= 0xD800 && code <= 0xDFFF)) return 0;
  return length;
}

// Characters that end, start or visually rearrange a line wherever the log is read.
bool log_text_escaped(char32_t code) {
  return code < 0x20 || (code >= 0x7F && code <= 0x9F) || code == 0x2028 || code == 0x2029 ||
         (code >= 0x200E && code <= 0x200F) || (code >= 0x202A && code <= 0x202E) || (code >= 0x2066 && code <= 0x2069);
}

void log_text_escape(char32_t code, bool raw_byte, std::string& into) {
  static constexpr char kHex[] = "0123456789abcdef";
  into.clear();
  if (code == '\n') into = "\\n";
  else if (code == '\r') into = "\\r";
  else if (code == '\t') into = "\\t";
  else if (raw_byte || code < 0x80) into = {'\\', 'x', kHex[(code >> 4) & 0xF], kHex[code & 0xF]};
  else into = {'\\', 'u', kHex[(code >> 12) & 0xF], kHex[(code >> 8) & 0xF], kHex[(code >> 4) & 0xF], kHex[code & 0xF]};
}

}  // namespace

void append_log_text(std::string_view text, spdlog::memory_buf_t& out, std::size_t max_bytes) {
  max_bytes = std::max(max_bytes, 2 * kCutMarkerRoom);
  const bool plain = std::all_of(text.begin(), text.end(), [](char c) { return c >= 0x20 && c < 0x7F; });
  if (plain && text.size() <= max_bytes) {  // the common case: one scan, one copy
    out.append(text.data(), text.data() + text.size());
    return;
  }
  const std::size_t start = out.size();
  const std::size_t room = max_bytes - kCutMarkerRoom;
  std::string escape;
  std::size_t i = 0;
  while (i < text.size()) {
    char32_t code = 0;
    const std::size_t length = log_text_sequence(text, i, code);
    const bool raw_byte = length == 0;
    if (raw_byte) code = static_cast<unsigned char>(text[i]);
    const bool escaped = raw_byte || log_text_escaped(code);
    if (escaped) log_text_escape(code, raw_byte, escape);
    const std::size_t width = escaped ? escape.size() : length;
    if (out.size() - start + width > room) break;
    if (escaped) out.append(escape.data(), escape.data() + escape.size());
    else out.append(text.data() + i, text.data() + i + length);
    i += raw_byte ? 1 : length;
  }
  if (i < text.size()) {
    const std::string marker = "...[+" + std::to_string(text.size() - i) + " bytes]";
    out.append(marker.data(), marker.data() + marker.size());
  }
}

std::string log_text(std::string_view text, std::size_t max_bytes) {
  spdlog::memory_buf_t buffer;
  append_log_text(text, buffer, max_bytes);
  return std::string(buffer.data(), buffer.size());
}

}  // namespace rcand
