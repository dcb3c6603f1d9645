// The listening socket, on the accept loop (slots[0], a thread of its own). Without ServerOptions::priority it hands
// each connection to a worker loop round-robin and closes those beyond the limits. With it, new connections stay on
// the accept loop while they send priority requests (see Session), and those beyond the limits join the busy lane.
#pragma once

#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/steady_timer.hpp>

#include <cstddef>
#include <cstdint>
#include <deque>
#include <memory>
#include <string>
#include <string_view>

#include "libs/http/server_core.hpp"
#include "libs/http/session.hpp"

namespace rcand::http::detail {

class Listener {
 public:
  // Binds at once (caller's thread), without listening yet: the address is taken, connections are refused until
  // start(). Throws std::runtime_error "cannot listen on <shown>: <reason>".
  // `tls`: every connection speaks TLS (core.tls_context) and goes straight to a worker loop, where its handshake
  // runs; none is read on the accept loop and none joins the busy lane.
  Listener(ServerCore& core, const boost::asio::ip::tcp::endpoint& endpoint, std::string_view shown, bool tls = false);
  std::uint16_t port() const;
  // Listens and queues the first accept; the loop then runs on slot 0's thread. Throws as the constructor does.
  void start();
  // Slot 0's thread only.
  void close() noexcept;

 private:
  void accept();
  void on_accept(boost::system::error_code ec, IoSlot& slot, Stream::socket_type socket);
  // A connection beyond the limits: into the busy lane (making room when full), or closed without priority.
  void admit_busy(Stream::socket_type socket, std::string address);

  ServerCore& core_;
  const bool tls_;
  const std::string shown_;
  boost::asio::ip::tcp::acceptor acceptor_;
  boost::asio::steady_timer backoff_;  // after accept errors such as EMFILE, so a full fd table does not spin us
  // A full lane evicts one waiter for a newcomer from `newcomer` (the rule: busy_lane.hpp); false: refuse it.
  bool make_room(std::string_view newcomer);

  struct BusyWaiter {
    std::weak_ptr<Session> session;
    std::string address;
  };
  std::deque<BusyWaiter> busy_lane_;  // oldest first; the accept loop's only
};

}  // namespace rcand::http::detail
