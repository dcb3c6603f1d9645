// A connection's place in the server's limits (max_connections, max_connections_per_address, the busy lane): taken
// by the acceptor, released when the connection ends, on whichever loop that is. It moves with the connection from
// the accept loop to a worker loop, so the connection is counted once all along.
#pragma once

#include <string>

namespace rcand::http::detail {

struct ServerCore;

class ConnectionTicket {
 public:
  // `busy`: a connection beyond the limits, counted in the busy lane only.
  ConnectionTicket(ServerCore& core, std::string address, bool busy);
  ~ConnectionTicket();
  ConnectionTicket(const ConnectionTicket&) = delete;
  ConnectionTicket& operator=(const ConnectionTicket&) = delete;

  bool busy() const noexcept { return busy_; }

 private:
  ServerCore& core_;
  const std::string address_;
  const bool busy_;
};

}  // namespace rcand::http::detail
