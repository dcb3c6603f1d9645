// Untrusted text on its way to an error body, a log line, the audit log, a status or the dashboard: bounded in
// length, valid UTF-8, nothing that controls a terminal or reorders what a reader sees. The one helper the kernel,
// the services and the plugins all call (libs/base/bounded_text.hpp forwards here), so that no answer echoes a
// megabyte path, cuts a character in half or shows "stop" where the bytes say "pots".
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

namespace rcand::sdk {

// The bound for a user-supplied value quoted back (a path, a type, a key, a joint or pose name, a reason).
inline constexpr std::size_t kQuotedTextLimit = 200;

// Code points replaced by '?', besides invalid UTF-8: what changes how text is shown rather than being text.
//   C0 controls and DEL (U+0000-U+001F, U+007F): line breaks forge log lines, ESC drives terminals;
//   C1 controls (U+0080-U+009F): CSI (U+009B) is ESC [ on many terminals; NEL (U+0085) is a line break;
//   bidi formatting (U+202A-U+202E embeddings and overrides, U+2066-U+2069 isolates, U+200E/U+200F/U+061C marks):
//     U+202E makes "stop" display as the bytes read backwards; the marks are invisible and serve only to spoof;
//   line and paragraph separators (U+2028, U+2029): line breaks to JavaScript and to some log viewers.
constexpr bool is_unsafe_code_point(std::uint32_t cp) noexcept {
  return cp < 0x20 || (cp >= 0x7F && cp <= 0x9F) || cp == 0x061C || cp == 0x200E || cp == 0x200F ||
         (cp >= 0x2028 && cp <= 0x202E) || (cp >= 0x2066 && cp <= 0x2069);
}

namespace bounded_text_detail {

// The length of the well-formed UTF-8 sequence at text[i] (RFC 3629: no overlongs, no surrogates, at most
// U+10FFFF) and its code point, or 0 when it is not one.
constexpr std::size_t decode(std::string_view text, std::size_t i, std::uint32_t& cp) noexcept {
  const auto byte = [&](std::size_t k) { return static_cast<unsigned char>(text[i + k]); };
  const unsigned char lead = byte(0);
  if (lead < 0x80) {
    cp = lead;
    return 1;
  }
  const std::size_t length = lead >= 0xC2 && lead <= 0xDF ? 2 : (lead & 0xF0) == 0xE0 ? 3 : lead >= 0xF0 && lead <= 0xF4 ? 4 : 0;
  if (length == 0 || i + length > text.size()) return 0;
  for (std::size_t k = 1; k < length; ++k)
    if ((byte(k) & 0xC0) != 0x80) return 0;
  if (length == 3 && ((lead == 0xE0 && byte(1) < 0xA0) || (lead == 0xED && byte(1) >= 0xA0))) return 0;
  if (length == 4 && ((lead == 0xF0 && byte(1) < 0x90) || (lead == 0xF4 && byte(1) >= 0x90))) return 0;
  cp = length == 2 ? lead & 0x1Fu : length == 3 ? lead & 0x0Fu : lead & 0x07u;
  for (std::size_t k = 1; k < length; ++k) cp = (cp << 6) | (byte(k) & 0x3Fu);
  return length;
}

constexpr std::size_t decimal_digits(std::size_t n) noexcept {
  std::size_t digits = 1;
  for (; n >= 10; n /= 10) ++digits;
  return digits;
}

}  // namespace bounded_text_detail

// `text` with every invalid UTF-8 sequence and every unsafe code point (is_unsafe_code_point) replaced by '?', cut at
// a character boundary so the result is at most `max_bytes` (>= 32) long; a cut text ends in "...(+N bytes)" naming
// how much of the input was left out. Text that is already safe and short comes back unchanged.
inline std::string bounded_text(std::string_view text, std::size_t max_bytes = kQuotedTextLimit) {
  if (max_bytes < 32) max_bytes = 32;
  // Room for the marker "...(+N bytes)" with N at most text.size(): the result never exceeds max_bytes.
  const std::size_t marker = 12 + bounded_text_detail::decimal_digits(text.size());
  const std::size_t room = text.size() <= max_bytes ? max_bytes : max_bytes - (marker < max_bytes ? marker : max_bytes);
  std::string out;
  out.reserve(text.size() < room ? text.size() : room);
  std::size_t i = 0;
  while (i < text.size()) {
    std::uint32_t cp = 0;
    const std::size_t length = bounded_text_detail::decode(text, i, cp);
    const bool safe = length != 0 && !is_unsafe_code_point(cp);
    if (out.size() + (safe ? length : 1) > room) break;
    if (safe) out.append(text.substr(i, length));
    else out.push_back('?');
    i += length != 0 ? length : 1;
  }
  if (i < text.size()) out += "...(+" + std::to_string(text.size() - i) + " bytes)";
  return out;
}

}  // namespace rcand::sdk
