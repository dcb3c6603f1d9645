// The asynchronous HTTP/1.x server: a small pool of event loops (one per I/O thread), keep-alive, one request in
// flight per connection, strict limits. Handlers may answer later from any thread; nothing on the request path
// takes a lock shared between connections.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

#include "libs/http/handler.hpp"
#include "libs/http/server_options.hpp"

namespace rcand::http {

namespace detail {
struct ServerCore;
class Listener;
}  // namespace detail

class Server {
 public:
  // Throws std::invalid_argument naming the option at fault (io_threads, max_connections, timeouts) or for an
  // empty handler.
  Server(ServerOptions options, Handler handler);
  ~Server();  // stop()
  Server(const Server&) = delete;
  Server& operator=(const Server&) = delete;

  // Binds, listens and starts the I/O threads; returns the bound port. Throws std::runtime_error
  // "cannot listen on 127.0.0.1:8000: Address already in use" (or a bad address), or when already started; with
  // ServerOptions::tls first reads its files (TlsError naming the setting, libs/http/tls_context.hpp) and also binds
  // the loopback plain port.
  std::uint16_t start();
  // start()'s first half, for a caller that must hold the port before doing anything else (rcand claims it before
  // any plugin starts): resolves, reads the TLS files and binds the socket(s) without listening, so connections are
  // refused until start() and a second bind of the port (by a process already listening there) fails here. Returns
  // the bound port; throws as start() does. start() after it only listens and serves.
  std::uint16_t bind();
  // With ServerOptions::tls: the plain HTTP port bound on 127.0.0.1; 0 without TLS or before start.
  std::uint16_t plain_loopback_port() const;
  // With ServerOptions::tls, after start: reads `settings` anew (renewed files, other paths) for the connections
  // accepted from now on; open ones keep theirs. Throws TlsError (nothing changes then), std::logic_error when the
  // server does not serve TLS. Any thread.
  void reload_tls(const TlsSettings& settings);
  // Stops accepting, closes every connection, joins the I/O threads. Idempotent and thread-safe. Called from an I/O
  // thread (it should not be) it cannot join that thread and detaches it instead.
  void stop();
  // Connections currently open (accepted and not yet closed).
  std::size_t connection_count() const noexcept;
  // Whether the accept loop (where the e-stop is read and handled) runs a posted no-op within `within`: the liveness
  // the service watchdog reports. False before start and after stop. Any thread but the accept loop's.
  bool accept_loop_responsive(std::chrono::milliseconds within) const;

 private:
  void stop_locked() noexcept;
  std::uint16_t bind_locked();

  // Declaration order is destruction order in reverse: the listener (an acceptor on the core's first event loop)
  // goes before the core, which may outlive the Server while a Respond still holds it.
  std::shared_ptr<detail::ServerCore> core_;
  std::unique_ptr<detail::Listener> listener_;
  std::unique_ptr<detail::Listener> plain_listener_;  // with TLS: 127.0.0.1, plain HTTP
  std::vector<std::thread> threads_;
  mutable std::mutex lifecycle_;  // start() against stop(); never taken on the request path
  bool started_ = false;
  bool stopped_ = false;
};

}  // namespace rcand::http
