// Splitting and percent-decoding a request target into the path and query of a Request.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <string_view>

namespace rcand::http::detail {

// Decodes %XX escapes (and '+' as a space when asked). nullopt for a truncated or non-hex escape.
std::optional<std::string> percent_decode(std::string_view text, bool plus_is_space);

// Fills path and query from an origin-form ("/a?b=c"), absolute-form ("http://h/a?b=c") or asterisk-form target.
// Returns an empty string on success, else why the target was refused (for a 400 body; it never quotes the target,
// whose query may carry a token).
std::string parse_target(std::string_view target, std::string& path, std::map<std::string, std::string>& query);

}  // namespace rcand::http::detail
