// Listening address, threads, limits and timeouts of the HTTP server.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>

#include "libs/http/request.hpp"
#include "libs/http/response.hpp"
#include "libs/http/tls_settings.hpp"

namespace rcand::http {

// WebSocket upgrades (and only those: GET with "Upgrade: websocket") go to the upgrade hook first, on the I/O thread.
// It answers with one of: `take` set - the server hands the connection over (see upgrade.hpp) and forgets it (it no
// longer counts in max_connections nor is closed by stop(): the taker owns it); `refuse` set - that answer is sent
// as plain HTTP and the connection closes (401 without credentials, 503); neither - the request goes to the Handler
// like any other (which answers 404 for a path nobody upgrades). Must not block.
struct Upgraded;  // libs/http/upgrade.hpp
struct UpgradeVerdict {
  std::function<void(Upgraded&&)> take;
  std::optional<Response> refuse;
};
using UpgradeHandler = std::function<UpgradeVerdict(const Request&)>;

// Runs first for every request the server reads, WebSocket upgrades included, on the I/O thread (the accept thread for
// a stop): an answer refuses the request with it (then the connection closes); nullopt lets it go on to the upgrade
// hook or the Handler. Must be quick and must not block.
using ScreenHandler = std::function<std::optional<Response>(const Request&)>;

struct ServerOptions {
  std::string address = "127.0.0.1";                 // an IP address or a resolvable host name
  std::uint16_t port = 0;                            // 0 = any free port
  int io_threads = 2;                                // >= 1 worker loops, each on its own thread (plus the accept loop)
  std::size_t body_limit = 1024 * 1024;              // larger → 413 PAYLOAD_TOO_LARGE, then close
  std::chrono::milliseconds header_timeout{10'000};  // whole request (headers+body) must arrive within this,
                                                     // counted from its first byte (from accept for the first one)
  std::chrono::milliseconds idle_timeout{60'000};    // keep-alive connection idle between requests; also bounds
                                                     // writing one response to a client that does not read
  std::size_t max_connections = 10'000;              // beyond it a new connection is busy (see priority), logged once
  std::size_t max_connections_per_address = 256;     // one client address holds at most this many; beyond: busy
  UpgradeHandler upgrade;                            // empty: upgrade requests go to the Handler
  ScreenHandler screen;                              // empty: every request goes on
  // The requests nothing may delay or lock out (rcand: the e-stop). When set, the accept thread (an event loop of
  // its own, on which no other work ever waits) reads each new connection's requests and handles them there while
  // this says so; the first other request moves the connection to a worker loop for good. A connection beyond the limits is not
  // closed at once but joins the busy lane (at most busy_lane of them, the oldest evicted first, each given at most 2 s to send
  // its request): a priority request is answered, anything else gets 503 SERVER_BUSY with Retry-After. Unset: the acceptor hands
  // connections straight to the workers and closes those beyond the limits.
  std::function<bool(const Request&)> priority;
  std::size_t busy_lane = 256;  // more than a burst of silent connections can fill while a stop is being sent
  // Run first on each I/O thread: `accept_loop` true on the accept thread (rcand makes it real-time there).
  std::function<void(bool accept_loop)> on_thread_start;
  // A streamed answer (Response::stream) whose client takes longer than this to accept one part is closed: a viewer
  // that stopped reading holds one part and its socket buffers, and only for this long. One offered no part for this
  // long ends too (cleanly): a viewer that asks for (almost) no frames holds its connection no longer.
  std::chrono::milliseconds stream_stall_timeout{10'000};
  // Set: `address` serves HTTPS (and wss) only, TLS 1.2 or later (start() reads the files; errors are named, see
  // libs/http/tls_context.hpp), and plain HTTP is served on 127.0.0.1 at plain_loopback_port (unset: port + 1, or
  // any free port when port is 0), where the stop lane and the busy lane work as without TLS. TLS connections go to
  // a worker loop at once and their handshake runs there, never on the accept loop; beyond the connection limits
  // they are closed (no busy lane: that would mean handshakes on the accept loop).
  std::optional<TlsSettings> tls;
  std::optional<std::uint16_t> plain_loopback_port;
};

}  // namespace rcand::http
