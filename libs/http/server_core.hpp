// State shared by the listener, the sessions and every outstanding Respond. It owns the event loops, so a Respond
// that outlives the Server keeps them (stopped) alive and its late answer is simply dropped.
#pragma once

#include <spdlog/logger.h>
#include <boost/asio/io_context.hpp>

#include <atomic>
#include <cstddef>
#include <memory>
#include <mutex>
#include <string>
#include <unordered_map>
#include <vector>

#include "libs/http/handler.hpp"
#include "libs/http/server_options.hpp"

namespace boost::asio::ssl {
class context;
}

namespace rcand::http::detail {

class Session;

// One event loop run by one I/O thread. Sessions on it are single-threaded and need no strand.
struct IoSlot {
  boost::asio::io_context ioc{1};

  // Only on this slot's thread: remembers a session so stop() can close it even while it waits for a handler.
  void track(std::weak_ptr<Session> session);
  // Only on this slot's thread.
  void close_all() noexcept;

 private:
  std::vector<std::weak_ptr<Session>> sessions_;
  std::size_t prune_at_ = 64;
};

struct ServerCore : std::enable_shared_from_this<ServerCore> {
  ServerCore(ServerOptions options_in, Handler handler_in);

  const ServerOptions options;
  const Handler handler;
  const std::shared_ptr<spdlog::logger> log;
  std::atomic<std::size_t> connections{0};       // within the limits (ConnectionTicket)
  std::atomic<std::size_t> busy_connections{0};  // in the busy lane
  std::atomic<bool> stopping{false};
  std::atomic<bool> limit_logged{false};
  // With ServerOptions::tls: the context new TLS connections use (Server::reload_tls swaps it; a connection keeps
  // the one it began with).
  std::atomic<std::shared_ptr<boost::asio::ssl::context>> tls_context;

  // The acceptor's thread only: whether one more connection from `address` fits max_connections and
  // max_connections_per_address (only the acceptor adds connections, so the answer cannot be raced past).
  bool fits(const std::string& address) const;
  // Any thread (ConnectionTicket).
  void count_address(const std::string& address, int delta);
  // A worker loop, round-robin (any thread).
  IoSlot& next_worker() noexcept;
  bool is_priority(const Request& request) const;

  // Last member, so destroyed first: sessions freed from the loops' queues still use the members above.
  // slots[0] is the accept loop; slots[1..] are the workers (io_threads of them).
  std::vector<std::unique_ptr<IoSlot>> slots;

 private:
  mutable std::mutex address_mutex_;  // held for a map lookup or update only
  std::unordered_map<std::string, std::size_t> per_address_;
  std::atomic<std::size_t> next_worker_{0};
};

}  // namespace rcand::http::detail
