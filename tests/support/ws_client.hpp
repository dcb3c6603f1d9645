// A WebSocket client for tests and benchmarks (header-only, Beast): every wait is bounded (async operations run with
// run_for), so a silent server fails the test instead of hanging it.
#pragma once

#include <boost/asio/io_context.hpp>
#include <boost/beast/core/buffers_to_string.hpp>
#include <boost/beast/core/tcp_stream.hpp>
#include <boost/beast/websocket.hpp>

#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>

namespace rcand::test {

class WsClient {
 public:
  // Connects to 127.0.0.1:port and upgrades `target` with "Authorization: Bearer <token>" (none when empty) and
  // `headers` (an Origin, say). Returns the HTTP status of the upgrade answer: 101 on success.
  int connect(std::uint16_t port, const std::string& token, const std::string& target = "/ws/r2r",
              const std::string& host = "127.0.0.1", const std::map<std::string, std::string>& headers = {}) {
    namespace net = boost::asio;
    boost::beast::error_code result = net::error::would_block;
    boost::beast::get_lowest_layer(ws).async_connect(net::ip::tcp::endpoint(net::ip::make_address(host), port),
                                                     [&](boost::beast::error_code ec) { result = ec; });
    run(std::chrono::seconds(5));
    if (result) throw std::runtime_error("ws connect: " + result.message());
    ws.set_option(
        boost::beast::websocket::stream_base::decorator([token, headers](boost::beast::websocket::request_type& request) {
          if (!token.empty()) request.set(boost::beast::http::field::authorization, "Bearer " + token);
          for (const auto& [name, value] : headers) request.set(name, value);
        }));
    auto response = std::make_shared<boost::beast::websocket::response_type>();
    result = net::error::would_block;
    ws.async_handshake(*response, host + ":" + std::to_string(port), target, [&](boost::beast::error_code ec) { result = ec; });
    run(std::chrono::seconds(5));
    return static_cast<int>(response->result_int());
  }

  void send(const std::string& text) {
    boost::beast::error_code result = boost::asio::error::would_block;
    ws.text(true);
    ws.async_write(boost::asio::buffer(text), [&](boost::beast::error_code ec, std::size_t) { result = ec; });
    run(std::chrono::seconds(30));  // a flood test fills the socket: an ASan-built robot on a busy machine drains it late
    if (result) throw std::runtime_error("ws send: " + result.message());
  }

  // The next frame, or nullopt when the connection closed or nothing came within `timeout` (`error` says which).
  std::optional<std::string> read(std::chrono::milliseconds timeout = std::chrono::seconds(5),
                                  boost::beast::error_code* error = nullptr) {
    boost::beast::error_code result = boost::asio::error::would_block;
    ws.async_read(buffer, [&](boost::beast::error_code ec, std::size_t) { result = ec; });
    run(timeout);
    if (result == boost::asio::error::would_block) {  // timed out: abandon the read (the stream is done after this)
      boost::beast::get_lowest_layer(ws).cancel();
      run(std::chrono::seconds(1));
    }
    if (error) *error = result;
    if (result) return std::nullopt;
    std::string text = boost::beast::buffers_to_string(buffer.data());
    buffer.consume(buffer.size());
    return text;
  }

  boost::asio::io_context ioc;
  boost::beast::websocket::stream<boost::beast::tcp_stream> ws{ioc};
  boost::beast::flat_buffer buffer;

 private:
  void run(std::chrono::milliseconds timeout) {
    ioc.run_for(timeout);
    ioc.restart();
  }
};

}  // namespace rcand::test
