// Untrusted text on its way to a log line, the audit log or an error body: bounded in length, valid UTF-8, no
// control characters. One function, so that no caller can echo a megabyte header or cut a character in half.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>

namespace rcand {

// The default bound for a user-supplied value quoted back (a type, a key, a header, a reason).
inline constexpr std::size_t kQuotedTextLimit = 200;

// `text` with every invalid UTF-8 sequence and every control character (C0, DEL) replaced by '?', cut at a character
// boundary so the result (with the marker) is at most `max_bytes` (>= 32) long; a cut text ends in "...(+N bytes)"
// naming how much of the input was left out.
inline std::string bounded_text(std::string_view text, std::size_t max_bytes = kQuotedTextLimit) {
  if (max_bytes < 32) max_bytes = 32;
  std::string out;
  out.reserve(text.size() < max_bytes ? text.size() : max_bytes);
  const std::size_t room = text.size() <= max_bytes ? max_bytes : max_bytes - 24;  // leaves space for the marker
  std::size_t i = 0;
  while (i < text.size()) {
    const auto lead = static_cast<unsigned char>(text[i]);
    std::size_t length = lead < 0x80 ? 1 : (lead >> 5) == 0x6 ? 2 : (lead >> 4) == 0xE ? 3 : (lead >> 3) == 0x1E ? 4 : 0;
    bool valid = length != 0 && i + length <= text.size();
    for (std::size_t k = 1; valid && k < length; ++k) valid = (static_cast<unsigned char>(text[i + k]) & 0xC0) == 0x80;
    if (valid && length == 2) valid = lead >= 0xC2;  // overlong
    if (valid && length == 3) {
      const auto second = static_cast<unsigned char>(text[i + 1]);
      valid = !(lead == 0xE0 && second < 0xA0) && !(lead == 0xED && second >= 0xA0);  // overlong, surrogates
    }
    if (valid && length == 4) {
      const auto second = static_cast<unsigned char>(text[i + 1]);
      valid = !(lead == 0xF0 && second < 0x90) && !(lead == 0xF4 && second >= 0x90) && lead <= 0xF4;
    }
    const std::size_t emitted = valid ? length : 1;
    if (out.size() + emitted > room) break;
    if (!valid || (length == 1 && (lead < 0x20 || lead == 0x7F))) out.push_back('?');
    else out.append(text.substr(i, length));
    i += valid ? length : 1;
  }
  if (i < text.size()) out += "...(+" + std::to_string(text.size() - i) + " bytes)";
  return out;
}

}  // namespace rcand
