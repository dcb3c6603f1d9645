// A hostile client's connections for the flood and slow-loris drills (tests/integration/connection_flood_test.cpp)
// and their benchmark (bench/stop_under_flood.cpp): raw non-blocking sockets on loopback, and a timed stop.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "rcand_process.hpp"

namespace rcand::test::flood {

// Raises this process's open-files soft limit to its hard limit; returns the soft limit now.
std::size_t raise_open_files();
// A non-blocking connect to 127.0.0.1:port (completing in the background) from `source` (another loopback address
// such as "127.0.0.2": another host as far as rcand can tell), or 127.0.0.1; -1 when no descriptor is left.
int connect_to(std::uint16_t port, const char* source = nullptr);
// Waits (bounded) until the connection is established, then sends `bytes` (whatever the socket takes).
void send_when_connected(int fd, const std::string& bytes);
void send_now(int fd, const std::string& bytes);
void close_all(std::vector<int>& fds);

struct TimedStop {
  int status = 0;    // 0: no answer
  double ms = 0;     // connect() to the whole answer
  std::string error;  // the client's, when there was no answer
};
// POST /api/stop as the guest on a fresh connection.
TimedStop timed_stop(const RcandProcess& rcand);

}  // namespace rcand::test::flood
