#include "libs/http/listener.hpp"

#include <boost/asio/post.hpp>

#include <chrono>
#include <stdexcept>
#include <string>
#include <unordered_map>

#include "libs/http/connection_ticket.hpp"
#include "libs/http/session.hpp"

namespace rcand::http::detail {

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
  // Without priority requests the socket is born on its worker's loop, so the session never touches another
  // thread's loop; with them it is born here, where its first request is read.
  IoSlot& slot = core_.options.priority ? *core_.slots.front() : core_.next_worker();
  acceptor_.async_accept(slot.ioc, [this, &slot](boost::system::error_code ec, Stream::socket_type socket) {
    on_accept(ec, slot, std::move(socket));
  });
}

void Listener::on_accept(boost::system::error_code ec, IoSlot& slot, Stream::socket_type socket) {
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
  socket.set_option(tcp::no_delay(true), ignored);
  const auto remote = socket.remote_endpoint(ignored);
  std::string address = ignored ? std::string("unknown") : remote.address().to_string();
  try {
    if (!core_.fits(address)) {
      admit_busy(std::move(socket), std::move(address));
      return accept();
    }
    core_.limit_logged.store(false, std::memory_order_relaxed);
    const auto placement = core_.options.priority ? Session::Placement::AcceptLoop : Session::Placement::Worker;
    auto session = std::make_shared<Session>(core_, slot, std::move(socket),
                                             std::make_unique<ConnectionTicket>(core_, std::move(address), false), placement);
    if (&slot == core_.slots.front().get()) session->start();
    else net::post(slot.ioc, [session = std::move(session)] { session->start(); });
  } catch (const std::exception& e) {
    core_.log->error("cannot start a connection: {}", e.what());
  }
  accept();
}

void Listener::admit_busy(Stream::socket_type socket, std::string address) {
  if (!core_.limit_logged.exchange(true)) {
    core_.log->warn("connection limit reached ({} in all, {} per address); new connections {} until one ends",
                    core_.options.max_connections, core_.options.max_connections_per_address,
                    core_.options.priority ? "only get priority requests answered (503 for the rest)" : "are closed");
  }
  boost::system::error_code ignored;
  if (!core_.options.priority || core_.options.busy_lane == 0) {
    socket.close(ignored);
    return;
  }
  std::erase_if(busy_lane_, [](const BusyWaiter& waiter) { return waiter.session.expired(); });
  // Full: a waiter that has sent nothing goes (a slow-loris or a silent flood): the oldest from the newcomer's own
  // address, else from the address holding most of the lane, so a flood evicts itself and not the one operator. A
  // stop is sent with the connection: one whose bytes are waiting to be read is never evicted. When every waiter
  // has sent something, the newcomer is refused instead (those are answered soon).
  if (busy_lane_.size() >= core_.options.busy_lane && !evict_silent_waiter(address) &&
      !evict_silent_waiter(busiest_lane_address())) {
    socket.close(ignored);
    return;
  }
  std::string lane_address = address;
  auto session = std::make_shared<Session>(core_, *core_.slots.front(), std::move(socket),
                                           std::make_unique<ConnectionTicket>(core_, std::move(address), true),
                                           Session::Placement::BusyLane);
  busy_lane_.push_back({session, std::move(lane_address)});
  session->start();
}

std::string Listener::busiest_lane_address() const {
  std::unordered_map<std::string_view, std::size_t> held;
  std::string_view busiest;
  std::size_t most = 0;
  for (const auto& waiter : busy_lane_)
    if (const std::size_t count = ++held[waiter.address]; count > most) {
      most = count;
      busiest = waiter.address;
    }
  return std::string(busiest);
}

bool Listener::evict_silent_waiter(const std::string& address) {
  for (auto it = busy_lane_.begin(); it != busy_lane_.end(); ++it) {
    if (it->address != address) continue;
    auto waiter = it->session.lock();
    if (waiter && waiter->has_pending_input()) continue;
    if (waiter) waiter->close();
    busy_lane_.erase(it);
    return true;
  }
  return false;
}

}  // namespace rcand::http::detail
