// The one rule for the text of a log line (docs/architecture.md §2): every message rcand logs - the kernel's, a
// service's, a plugin's through the SDK logger - is written through append_log_text by the log formatter, so no
// call site can forget it and text from outside (an R2R source_id, a model's reply, a header) can never forge a line.
// Escaped: C0 controls (\n \r \t by name, the others as \xHH), DEL (\x7f), C1 controls (\u0080..\u009f), Unicode line
// and paragraph separators and bidirectional controls (\u2028, \u202e, ...), and every byte of invalid UTF-8 (\xHH);
// everything else passes unchanged. So a message never ends its line early and never starts one of its own (a
// journald "<N>" priority prefix is read only at a line's start, which is always rcand's own prefix), never repaints
// a terminal, and never turns a journal entry into a binary blob. A message longer than `max_bytes` (once escaped)
// is cut at a character boundary and ends in "...[+N bytes]": a 200 KB model reply costs one bounded line, and no
// line reaches journald's LineMax (48 KiB by default), past which journald would split it into a new line.
// Printable ASCII within the bound - nearly every line - is copied with one scan and no allocation.
#pragma once

#include <spdlog/common.h>

#include <cstddef>
#include <string>
#include <string_view>

namespace rcand {

inline constexpr std::size_t kMaxLogMessageBytes = 4096;

void append_log_text(std::string_view text, spdlog::memory_buf_t& out, std::size_t max_bytes = kMaxLogMessageBytes);
std::string log_text(std::string_view text, std::size_t max_bytes = kMaxLogMessageBytes);

}  // namespace rcand
