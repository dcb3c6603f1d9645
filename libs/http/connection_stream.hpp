// One server connection's byte stream: plain TCP, or TLS over TCP (runtime.listen.tls), chosen per connection at
// run time. It is an Asio/Beast AsyncStream either way, so the HTTP session, Beast's websocket::stream (both
// WebSockets take connections from the server as http::UpgradeStream, which is this) and its timeouts work on it
// unchanged: next_layer() is always the TCP stream (its deadlines, socket(), close()), whatever sits on top.
#pragma once

#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/ssl/context.hpp>
#include <boost/beast/core/basic_stream.hpp>
#include <boost/beast/core/role.hpp>
#include <boost/beast/ssl/ssl_stream.hpp>
#include <boost/beast/websocket/ssl.hpp>
#include <boost/beast/websocket/teardown.hpp>

#include <memory>
#include <optional>
#include <utility>

namespace rcand::http {

// The concrete executor (not any_io_executor) avoids type erasure on every operation.
using TcpStream = boost::beast::basic_stream<boost::asio::ip::tcp, boost::asio::io_context::executor_type>;
using TlsStream = boost::beast::ssl_stream<TcpStream>;

class ConnectionStream {
 public:
  using executor_type = TcpStream::executor_type;
  using next_layer_type = TcpStream;

  // Plain TCP, on an accepted socket or unconnected (a client that dials).
  explicit ConnectionStream(TcpStream tcp) : plain_(std::move(tcp)) {}
  explicit ConnectionStream(boost::asio::io_context& ioc) : plain_(std::in_place, ioc) {}
  // TLS over `tcp` with `context` (kept alive with the stream); the handshake is the owner's to make (tls()).
  ConnectionStream(TcpStream tcp, std::shared_ptr<boost::asio::ssl::context> context)
      : context_(std::move(context)), tls_(std::make_unique<TlsStream>(std::move(tcp), *context_)) {}
  ConnectionStream(ConnectionStream&&) noexcept = default;  // move-constructible only, like the streams it holds

  bool is_tls() const noexcept { return tls_ != nullptr; }
  // The TLS layer (handshake, shutdown, SSL*), or null for plain TCP.
  TlsStream* tls() noexcept { return tls_.get(); }

  TcpStream& next_layer() noexcept { return tls_ ? tls_->next_layer() : *plain_; }
  const TcpStream& next_layer() const noexcept { return tls_ ? tls_->next_layer() : *plain_; }
  executor_type get_executor() noexcept { return next_layer().get_executor(); }
  TcpStream::socket_type& socket() noexcept { return next_layer().socket(); }
  template <class Duration> void expires_after(Duration duration) { next_layer().expires_after(duration); }
  template <class TimePoint> void expires_at(TimePoint when) { next_layer().expires_at(when); }
  void expires_never() { next_layer().expires_never(); }
  void close() { next_layer().close(); }

  template <class MutableBuffers, class Handler> void async_read_some(const MutableBuffers& buffers, Handler&& handler) {
    if (tls_) tls_->async_read_some(buffers, std::forward<Handler>(handler));
    else plain_->async_read_some(buffers, std::forward<Handler>(handler));
  }
  template <class ConstBuffers, class Handler> void async_write_some(const ConstBuffers& buffers, Handler&& handler) {
    if (tls_) tls_->async_write_some(buffers, std::forward<Handler>(handler));
    else plain_->async_write_some(buffers, std::forward<Handler>(handler));
  }

  // How Beast's websocket::stream closes the connection after a close frame (found by argument-dependent lookup).
  friend void teardown(boost::beast::role_type role, ConnectionStream& stream, boost::system::error_code& ec) {
    using boost::beast::websocket::teardown;
    if (stream.tls_) teardown(role, *stream.tls_, ec);
    else teardown(role, *stream.plain_, ec);
  }
  template <class Handler> friend void async_teardown(boost::beast::role_type role, ConnectionStream& stream, Handler&& handler) {
    using boost::beast::websocket::async_teardown;
    if (stream.tls_) async_teardown(role, *stream.tls_, std::forward<Handler>(handler));
    else async_teardown(role, *stream.plain_, std::forward<Handler>(handler));
  }

 private:
  std::optional<TcpStream> plain_;                      // engaged without TLS
  std::shared_ptr<boost::asio::ssl::context> context_;  // before tls_, so it outlives it
  std::unique_ptr<TlsStream> tls_;                      // engaged with TLS
};

}  // namespace rcand::http
