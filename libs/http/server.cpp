#include "libs/http/server.hpp"

#include <boost/asio/executor_work_guard.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/post.hpp>

#include <pthread.h>

#include <exception>
#include <future>
#include <stdexcept>
#include <string>

#include "libs/http/listener.hpp"
#include "libs/http/server_core.hpp"
#include "libs/http/tls_context.hpp"

namespace rcand::http {

namespace net = boost::asio;
using net::ip::tcp;

namespace {

void validate(const ServerOptions& options, const Handler& handler) {
  auto bad = [](const std::string& what) { throw std::invalid_argument("http server option " + what); };
  if (options.io_threads < 1 || options.io_threads > 256) {
    bad("io_threads must be between 1 and 256, got " + std::to_string(options.io_threads));
  }
  if (options.max_connections < 1) bad("max_connections must be at least 1, got 0");
  if (options.max_connections_per_address < 1) bad("max_connections_per_address must be at least 1, got 0");
  if (options.header_timeout.count() <= 0) {
    bad("header_timeout must be positive, got " + std::to_string(options.header_timeout.count()) + " ms");
  }
  if (options.idle_timeout.count() <= 0) {
    bad("idle_timeout must be positive, got " + std::to_string(options.idle_timeout.count()) + " ms");
  }
  if (!handler) throw std::invalid_argument("http server: the handler is empty");
}

std::string shown_address(const ServerOptions& options) {
  const bool v6 = options.address.find(':') != std::string::npos;
  return (v6 ? "[" + options.address + "]" : options.address) + ":" + std::to_string(options.port);
}

// With TLS: where plain HTTP stays available for local tools (server_options.hpp).
std::uint16_t plain_port_for(const ServerOptions& options) {
  if (options.plain_loopback_port) return *options.plain_loopback_port;
  return options.port == 0 || options.port == 65535 ? 0 : static_cast<std::uint16_t>(options.port + 1);
}

tcp::endpoint resolve_listen_endpoint(const ServerOptions& options, const std::string& shown) {
  boost::system::error_code ec;
  auto address = net::ip::make_address(options.address, ec);
  if (!ec) return {address, options.port};
  net::io_context ioc;
  tcp::resolver resolver(ioc);
  auto results = resolver.resolve(options.address, std::to_string(options.port), ec);
  if (ec || results.empty()) {
    throw std::runtime_error("cannot listen on " + shown + ": cannot resolve '" + options.address +
                             "': " + (ec ? ec.message() : std::string{"no address"}));
  }
  return results.begin()->endpoint();
}

void run_loop(const std::shared_ptr<detail::ServerCore>& core, detail::IoSlot& slot) {
  auto guard = net::make_work_guard(slot.ioc);
  for (;;) {
    try {
      slot.ioc.run();
      return;
    } catch (const std::exception& e) {  // our handlers catch their own; keep the loop alive regardless
      core->log->error("http I/O loop: unexpected exception: {}", e.what());
    } catch (...) {
      core->log->error("http I/O loop: unexpected non-standard exception");
    }
  }
}

}  // namespace

Server::Server(ServerOptions options, Handler handler) {
  validate(options, handler);
  core_ = std::make_shared<detail::ServerCore>(std::move(options), std::move(handler));
}

Server::~Server() { stop(); }

std::uint16_t Server::bind() {
  std::lock_guard lock(lifecycle_);
  if (started_) throw std::runtime_error("http server already started");
  return bind_locked();
}

std::uint16_t Server::bind_locked() {
  if (listener_) return listener_->port();
  const auto& options = core_->options;
  const std::string shown = shown_address(options);
  const auto endpoint = resolve_listen_endpoint(options, shown);
  if (options.tls) core_->tls_context.store(make_server_tls_context(*options.tls));

  // The accept loop, then io_threads workers (server_core.hpp).
  for (int i = 0; i <= options.io_threads; ++i) core_->slots.push_back(std::make_unique<detail::IoSlot>());
  try {
    listener_ = std::make_unique<detail::Listener>(*core_, endpoint, shown, options.tls.has_value());
    if (options.tls) {
      const std::uint16_t plain = plain_port_for(options);
      plain_listener_ = std::make_unique<detail::Listener>(*core_, tcp::endpoint(net::ip::address_v4::loopback(), plain),
                                                           "127.0.0.1:" + std::to_string(plain) + " (plain HTTP)");
    }
  } catch (...) {
    listener_.reset();
    plain_listener_.reset();
    core_->slots.clear();
    throw;
  }
  return listener_->port();
}

std::uint16_t Server::start() {
  std::lock_guard lock(lifecycle_);
  if (started_) throw std::runtime_error("http server already started");
  const auto& options = core_->options;
  const std::string shown = shown_address(options);
  bind_locked();
  listener_->start();
  if (plain_listener_) plain_listener_->start();
  started_ = true;
  try {
    for (std::size_t i = 0; i < core_->slots.size(); ++i) {
      threads_.emplace_back([core = core_, slot = core_->slots[i].get(), i] {
        const std::string name = i == 0 ? "http.accept" : "http.io." + std::to_string(i);
        pthread_setname_np(pthread_self(), name.c_str());
        if (core->options.on_thread_start) core->options.on_thread_start(i == 0);
        run_loop(core, *slot);
      });
    }
  } catch (const std::exception& e) {
    stop_locked();
    throw std::runtime_error(std::string{"cannot start the http I/O threads: "} + e.what());
  }
  const auto port = listener_->port();
  const std::string host = shown.substr(0, shown.rfind(':'));
  if (!plain_listener_) {
    core_->log->info("listening on {}", host + ":" + std::to_string(port));
  } else {
    core_->log->info("listening on {}:{} with TLS{}; plain HTTP on 127.0.0.1:{} (loopback only)", host, port,
                     options.tls->client_ca_file ? " (client certificates required)" : "", plain_listener_->port());
  }
  return port;
}

void Server::stop() {
  std::lock_guard lock(lifecycle_);
  stop_locked();
}

void Server::stop_locked() noexcept {
  if (!started_ || stopped_) return;
  stopped_ = true;
  core_->stopping.store(true, std::memory_order_release);
  for (std::size_t i = 0; i < core_->slots.size(); ++i) {
    auto* slot = core_->slots[i].get();
    auto* listener = i == 0 ? listener_.get() : nullptr;
    auto* plain_listener = i == 0 ? plain_listener_.get() : nullptr;
    try {
      net::post(slot->ioc, [slot, listener, plain_listener] {
        if (listener) listener->close();
        if (plain_listener) plain_listener->close();
        slot->close_all();
        slot->ioc.stop();
      });
    } catch (...) {  // cannot queue the closes: still stop the loop, connections close with the core
      slot->ioc.stop();
    }
  }
  std::vector<bool> joined;
  joined.reserve(threads_.size());
  for (auto& thread : threads_) {
    if (thread.get_id() == std::this_thread::get_id()) {
      thread.detach();  // stop() from a handler: that loop exits once the handler returns
      joined.push_back(false);
    } else {
      thread.join();
      joined.push_back(true);
    }
  }
  // Run what the closes completed (cancelled reads, writes), so idle sessions are freed now, not at destruction.
  for (std::size_t i = 0; i < core_->slots.size() && i < joined.size(); ++i) {
    if (!joined[i]) continue;
    try {
      core_->slots[i]->ioc.restart();
      core_->slots[i]->ioc.poll();
    } catch (const std::exception& e) {
      core_->log->error("http stop: {}", e.what());
    }
  }
  threads_.clear();
  core_->log->info("stopped");
}

bool Server::accept_loop_responsive(std::chrono::milliseconds within) const {
  std::shared_ptr<detail::ServerCore> core;
  {
    std::lock_guard lock(lifecycle_);
    if (!started_ || stopped_ || core_->slots.empty()) return false;
    core = core_;
  }
  auto ran = std::make_shared<std::promise<void>>();
  auto done = ran->get_future();
  boost::asio::post(core->slots.front()->ioc, [ran] { ran->set_value(); });
  return done.wait_for(within) == std::future_status::ready;
}

std::uint16_t Server::plain_loopback_port() const {
  std::lock_guard lock(lifecycle_);
  return plain_listener_ ? plain_listener_->port() : 0;
}

void Server::reload_tls(const TlsSettings& settings) {
  if (!core_->options.tls) throw std::logic_error("this server was started without TLS");
  core_->tls_context.store(make_server_tls_context(settings));
}

std::size_t Server::connection_count() const noexcept {
  return core_->connections.load(std::memory_order_relaxed) + core_->busy_connections.load(std::memory_order_relaxed);
}

}  // namespace rcand::http
