// An HTTP response as a Handler produces it. The server adds Server, Content-Length and Connection itself.
#pragma once

#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace rcand::http {

struct Response {
  int status = 200;  // 200..599; anything else is replaced by a 500 (and logged)
  std::string content_type = "application/json";
  std::string body;
  // Extra headers. Content-Length, Transfer-Encoding and Server are the server's and are dropped;
  // "Connection: close" closes the connection after this response. Names or values with CR, LF or NUL are dropped.
  std::vector<std::pair<std::string, std::string>> headers;
};

// The JSON error body of docs/protocol.md §4: {"error": message, "code": code, "status": status}. Invalid UTF-8 in the
// message is replaced, never thrown on.
Response error_response(int status, std::string_view code, std::string_view message);

}  // namespace rcand::http
