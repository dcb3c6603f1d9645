#include "listener.hpp"

#include <boost/asio/post.hpp>

#include <chrono>
#include <stdexcept>
#include <string>

#include "session.hpp"

namespace rcand::kernel::http::detail {

namespace net = boost::asio;
using net::ip::tcp;

namespace {

constexpr std::chrono::milliseconds kAcceptBackoff{100};

[[noreturn]] void fail(std::string_view shown, const boost::system::error_code& ec) {
  throw std::runtime_error("cannot listen on " + std::string{shown} + ": " + ec.message());
}

}  // namespace

Listener::Listener(ServerCore& core, const tcp::endpoint& endpoint, std::string_view shown)
    : core_(core), acceptor_(core.slots.front()->ioc), backoff_(core.slots.front()->ioc) {
  boost::system::error_code ec;
  acceptor_.open(endpoint.protocol(), ec);
  if (ec) fail(shown, ec);
  acceptor_.set_option(net::socket_base::reuse_address(true), ec);
  if (ec) fail(shown, ec);
  acceptor_.bind(endpoint, ec);
  if (ec) fail(shown, ec);
  acceptor_.listen(net::socket_base::max_listen_connections, ec);
  if (ec) fail(shown, ec);
}

std::uint16_t Listener::port() const {
  boost::system::error_code ec;
  auto endpoint = acceptor_.local_endpoint(ec);
  return ec ? 0 : endpoint.port();
}

void Listener::start() {
  net::post(core_.slots.front()->ioc, [this] { accept(); });
}

void Listener::close() noexcept {
  boost::system::error_code ec;
  acceptor_.close(ec);
  backoff_.cancel(ec);
}

void Listener::accept() {
  if (!acceptor_.is_open()) return;
  IoSlot& slot = *core_.slots[next_slot_++ % core_.slots.size()];
  // The socket is born on its session's loop, so the session never touches another thread's loop.
  acceptor_.async_accept(slot.ioc, [this, &slot](boost::system::error_code ec, Stream::socket_type socket) {
    on_accept(ec, slot, std::move(socket));
  });
}

void Listener::on_accept(boost::system::error_code ec, IoSlot& slot,
                         Stream::socket_type socket) {
  if (ec == net::error::operation_aborted || core_.stopping.load(std::memory_order_acquire)) return;
  if (ec) {
    if (ec == net::error::connection_aborted) return accept();  // the client gave up while queued
    core_.log->warn("accept failed: {}; retrying in {} ms", ec.message(), kAcceptBackoff.count());
    backoff_.expires_after(kAcceptBackoff);
    backoff_.async_wait([this](boost::system::error_code wait_ec) {
      if (!wait_ec) accept();
    });
    return;
  }
  boost::system::error_code ignored;
  // Only this thread adds connections, so the check cannot be raced past the limit.
  if (core_.connections.load(std::memory_order_relaxed) >= core_.options.max_connections) {
    if (!core_.limit_logged.exchange(true)) {
      core_.log->warn("connection limit of {} reached; closing new connections until one ends",
                      core_.options.max_connections);
    }
    socket.close(ignored);
    return accept();
  }
  core_.limit_logged.store(false, std::memory_order_relaxed);
  socket.set_option(tcp::no_delay(true), ignored);
  try {
    auto session = std::make_shared<Session>(core_, slot, std::move(socket));
    net::post(slot.ioc, [session = std::move(session)] { session->start(); });
  } catch (const std::exception& e) {
    core_.log->error("cannot start a connection: {}", e.what());
  }
  accept();
}

}  // namespace rcand::kernel::http::detail
