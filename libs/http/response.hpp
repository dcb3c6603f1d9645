// An HTTP response as a Handler produces it. The server adds Server, Content-Length and Connection itself.
#pragma once

#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace rcand::http {

class ResponseStream;  // libs/http/response_stream.hpp

struct Response {
  int status = 200;  // 200..599; anything else is replaced by a 500 (and logged)
  std::string content_type = "application/json";
  std::string body;
  // Extra headers. Content-Length, Transfer-Encoding and Server are the server's and are dropped;
  // "Connection: close" closes the connection after this response. Names or values with CR, LF or NUL are dropped.
  std::vector<std::pair<std::string, std::string>> headers;
  // Set: a streamed answer. The header goes out without Content-Length (and `body` is ignored), then the stream's
  // parts as they are pushed; the connection closes when the stream ends or the client leaves.
  std::shared_ptr<ResponseStream> stream = nullptr;
};

// The JSON error body of docs/protocol.md §4: {"error": message, "code": code, "status": status}. Invalid UTF-8 in the
// message is replaced, never thrown on.
Response error_response(int status, std::string_view code, std::string_view message);

}  // namespace rcand::http
