// The hostile swarm of issue 28 #3: nine peers that each misbehave in their own way when sent a forwarded stop, for
// the broadcast-stop regression test (tests/integration/swarm_hostile_peers_test.cpp) and its benchmark
// (bench/broadcast_stop_hostile.cpp). All but `refused` are served by one thread of this process (asio), so they cost
// the machine what real misbehaving robots would cost it.
//   sleeper       accepts and never reads or answers (closes after `hold`)
//   byte_by_byte  answers a status line, then one header byte every `trickle` (an endless header, slowly)
//   garbage       answers 1 KiB of random bytes, then closes
//   chunked       an endless chunked body, 4 KiB chunks as fast as the socket takes them
//   headers       endless header lines as fast as the socket takes them
//   rst           reads the request, then resets the connection (RST)
//   backlog       listens with a full backlog and never accepts: new SYNs are dropped, connect() hangs
//   mistyped      a 300 KB JSON answer delimited by the close, "motors_stopped": "yes" (a string, not a boolean)
//   refused       nobody listens: connection refused
#pragma once

#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>

#include <chrono>
#include <cstdint>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "swarm_lab.hpp"

namespace rcand::test {

class HostilePeers {
 public:
  struct Options {
    std::chrono::milliseconds hold{3000};     // how long a sleeper or a trickle keeps a connection
    std::chrono::milliseconds trickle{10};    // byte_by_byte: one byte this often
    std::size_t mistyped_bytes = 300 * 1024;  // mistyped: the answer's size
  };
  HostilePeers() : HostilePeers(Options{}) {}
  explicit HostilePeers(Options options);
  ~HostilePeers();  // closes every connection, joins the thread
  HostilePeers(const HostilePeers&) = delete;
  HostilePeers& operator=(const HostilePeers&) = delete;

  // The nine peers as swarm.yaml entries (names as above), each on 127.0.0.1 with the owner token.
  std::vector<SwarmEntry> entries() const;
  static std::vector<std::string> names();

 private:
  struct Listener;
  void accept_next(const std::shared_ptr<Listener>& listener);

  Options options_;
  boost::asio::io_context io_;
  std::vector<std::shared_ptr<Listener>> listeners_;
  int backlog_fd_ = -1;
  std::vector<int> backlog_fillers_;
  std::uint16_t backlog_port_ = 0;
  std::uint16_t refused_port_ = 0;
  std::thread thread_;
};

// One timed POST /api/stop + X-Swarm-Broadcast: from the connect() to the whole answer.
struct TimedBroadcast {
  int status = 0;  // 0: no answer (then `error` says why)
  double ms = 0;
  std::int64_t sent_us = 0;  // steady clock (the one rcand's "received_us" reads), at the connect()
  std::string body;
  std::string error;
};

// `count` broadcast stops to 127.0.0.1:port, all in flight at once on fresh connections (one client thread, asio),
// each given up after `give_up`. In the order sent.
std::vector<TimedBroadcast> concurrent_broadcast_stops(std::uint16_t port, int count, std::chrono::milliseconds give_up,
                                                       const std::string& token = "guest-token");

}  // namespace rcand::test
