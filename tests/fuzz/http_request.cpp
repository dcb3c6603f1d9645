// libFuzzer target: raw bytes as they arrive on a connection, through Beast's request parser with the server's
// limits and the server's own request building (request_builder), then the real Api of a simulated robot.
// Several pipelined requests in one input are handled in order, while each keeps the connection alive.
#include <boost/asio/buffer.hpp>
#include <boost/beast/http/error.hpp>

#include <cstddef>
#include <cstdint>
#include <string_view>

#include "fuzz_check.hpp"
#include "request_builder.hpp"
#include "sim_robot.hpp"

namespace {

namespace bhttp = boost::beast::http;
using rcand::http::detail::build_request;
using rcand::http::detail::configure_parser;
using rcand::http::detail::RequestParser;

constexpr std::size_t kBodyLimit = 1024 * 1024;  // ServerOptions' default
constexpr int kMaxRequestsPerInput = 16;

// One request from the front of `bytes`; false when the connection would end here (error, incomplete, close).
bool serve_one(std::string_view& bytes) {
  RequestParser parser;
  configure_parser(parser, kBodyLimit);
  boost::beast::error_code ec;
  while (!parser.is_done()) {
    const std::size_t used = parser.put(boost::asio::buffer(bytes.data(), bytes.size()), ec);
    RCAND_FUZZ_CHECK(used <= bytes.size(), "the parser consumed more than it was given");
    bytes.remove_prefix(used);
    if (ec && ec != bhttp::error::need_more) return false;  // the server answers 400/413/431 and closes
    // No progress (the input ended inside a header or a body): the server would wait for more bytes, then time out.
    if (used == 0 && !parser.is_done()) return false;
    ec = {};
  }
  rcand::http::Request request;
  if (!build_request(parser.get(), "127.0.0.1:40000", request).empty()) return false;  // 400, close
  const bool keep_alive = parser.get().keep_alive();
  rcand::fuzz::call(std::move(request));
  return keep_alive;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::string_view bytes(reinterpret_cast<const char*>(data), size);
  for (int served = 0; served < kMaxRequestsPerInput && !bytes.empty(); ++served)
    if (!serve_one(bytes)) break;
  rcand::fuzz::reset_robot();
  return 0;
}
