// From bytes Beast parsed to the Request a Handler receives. The server's sessions and the HTTP fuzz target
// (tests/fuzz/http_request.cpp) share it, so the fuzzer exercises exactly what the server does.
#pragma once

#include <boost/beast/http/parser.hpp>
#include <boost/beast/http/string_body.hpp>

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>

#include "libs/http/request.hpp"

namespace rcand::http::detail {

using RequestParser = boost::beast::http::request_parser<boost::beast::http::string_body>;

inline constexpr std::uint32_t kHeaderLimit = 16 * 1024;

// The limits every request is parsed under: kHeaderLimit, `body_limit`, and eager body parsing.
void configure_parser(RequestParser& parser, std::size_t body_limit);

struct HeaderRefusal {
  int status;
  std::string code, message;
};
// What rcand refuses in a parsed header, before reading any body: a method not in upper case (methods are
// case-sensitive: "get" is not GET), HTTP/1.1 without Host (RFC 9112 §3.2), and any transfer coding but chunked
// alone (RFC 9112 §6.1: 501; "gzip, chunked" would otherwise reach the handler still compressed).
std::optional<HeaderRefusal> check_header(const RequestParser::value_type& message);

// Fills `out` from a complete message (its body is moved out). Returns "" on success, else why the request is
// refused with a 400 (never quoting the target, whose query may carry a token).
std::string build_request(RequestParser::value_type& message, std::string remote, Request& out);

}  // namespace rcand::http::detail
