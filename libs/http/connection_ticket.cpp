#include "libs/http/connection_ticket.hpp"

#include "libs/http/server_core.hpp"

namespace rcand::http::detail {

ConnectionTicket::ConnectionTicket(ServerCore& core, std::string address, bool busy)
    : core_(core), address_(std::move(address)), busy_(busy) {
  (busy_ ? core_.busy_connections : core_.connections).fetch_add(1, std::memory_order_relaxed);
  if (!busy_) core_.count_address(address_, +1);
}

ConnectionTicket::~ConnectionTicket() {
  if (!busy_) core_.count_address(address_, -1);
  (busy_ ? core_.busy_connections : core_.connections).fetch_sub(1, std::memory_order_relaxed);
}

}  // namespace rcand::http::detail
