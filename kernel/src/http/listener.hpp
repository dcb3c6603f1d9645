// The listening socket: accepts on the first event loop and spreads connections round-robin over all of them.
#pragma once

#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/steady_timer.hpp>

#include <cstddef>
#include <cstdint>
#include <string_view>

#include "server_core.hpp"
#include "session.hpp"

namespace rcand::kernel::http::detail {

class Listener {
 public:
  // Binds and listens at once (caller's thread). Throws std::runtime_error "cannot listen on <shown>: <reason>".
  Listener(ServerCore& core, const boost::asio::ip::tcp::endpoint& endpoint, std::string_view shown);
  std::uint16_t port() const;
  // Queues the first accept; the loop then runs on slot 0's thread.
  void start();
  // Slot 0's thread only.
  void close() noexcept;

 private:
  void accept();
  void on_accept(boost::system::error_code ec, IoSlot& slot, Stream::socket_type socket);

  ServerCore& core_;
  boost::asio::ip::tcp::acceptor acceptor_;
  boost::asio::steady_timer backoff_;  // after accept errors such as EMFILE, so a full fd table does not spin us
  std::size_t next_slot_ = 0;
};

}  // namespace rcand::kernel::http::detail
