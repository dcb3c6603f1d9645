// Listening address, threads, limits and timeouts of the HTTP server.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <string>

namespace rcand::kernel::http {

struct ServerOptions {
  std::string address = "127.0.0.1";                // an IP address or a resolvable host name
  std::uint16_t port = 0;                           // 0 = any free port
  int io_threads = 2;                               // >= 1; each runs its own event loop
  std::size_t body_limit = 1024 * 1024;             // larger → 413 PAYLOAD_TOO_LARGE, then close
  std::chrono::milliseconds header_timeout{10'000};  // whole request (headers+body) must arrive within this,
                                                     // counted from its first byte (from accept for the first one)
  std::chrono::milliseconds idle_timeout{60'000};    // keep-alive connection idle between requests; also bounds
                                                     // writing one response to a client that does not read
  std::size_t max_connections = 10'000;             // beyond it new connections are closed at once (logged once)
};

}  // namespace rcand::kernel::http
