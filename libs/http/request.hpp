// An HTTP request as the server hands it to a Handler: fully read, decoded, owned by the handler.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <string_view>

namespace rcand::http {

struct Request {
  std::string method;                          // upper case
  std::string target;                          // as received
  std::string path;                            // percent-decoded path without the query
  std::map<std::string, std::string> query;    // percent-decoded (+ is space); the first of repeated keys wins
  std::map<std::string, std::string> headers;  // names lower-cased; repeated headers joined with ", "
  std::string body;
  std::string remote;   // "127.0.0.1:54321" ("[::1]:54321" for IPv6)
  bool secure = false;  // it came over TLS (an https:// or wss:// page's request)

  // The header's value, looked up by its lower-case name.
  std::optional<std::string_view> header(std::string_view lower_name) const;
};

// The address part of Request::remote: "127.0.0.1:54321" -> "127.0.0.1", "[::1]:54321" -> "::1" (what limits per client
// address count by).
std::string client_address(std::string_view remote);

}  // namespace rcand::http
