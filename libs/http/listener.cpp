#include "libs/http/listener.hpp"

#include <boost/asio/post.hpp>

#include <chrono>
#include <stdexcept>
#include <string>
#include <vector>

#include "libs/http/busy_lane.hpp"
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

Listener::Listener(ServerCore& core, const tcp::endpoint& endpoint, std::string_view shown, bool tls)
    : core_(core), tls_(tls), shown_(shown), acceptor_(core.slots.front()->ioc), backoff_(core.slots.front()->ioc) {
  boost::system::error_code ec;
  acceptor_.open(endpoint.protocol(), ec);
  if (ec) fail(shown, ec);
  acceptor_.set_option(net::socket_base::reuse_address(true), ec);
  if (ec) fail(shown, ec);
  acceptor_.bind(endpoint, ec);
  if (ec) fail(shown, ec);
}

std::uint16_t Listener::port() const {
  boost::system::error_code ec;
  auto endpoint = acceptor_.local_endpoint(ec);
  return ec ? 0 : endpoint.port();
}

void Listener::start() {
  boost::system::error_code ec;
  acceptor_.listen(net::socket_base::max_listen_connections, ec);
  if (ec) fail(shown_, ec);
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
  IoSlot& slot = core_.options.priority && !tls_ ? *core_.slots.front() : core_.next_worker();
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
    const auto placement = core_.options.priority && !tls_ ? Session::Placement::AcceptLoop : Session::Placement::Worker;
    auto session = std::make_shared<Session>(core_, slot, std::move(socket),
                                             std::make_unique<ConnectionTicket>(core_, std::move(address), false), placement,
                                             tls_ ? core_.tls_context.load() : nullptr);
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
  // TLS: closed too (its handshake would run here); a stop beyond the limits has the loopback plain port.
  if (!core_.options.priority || core_.options.busy_lane == 0 || tls_) {
    socket.close(ignored);
    return;
  }
  std::erase_if(busy_lane_, [](const BusyWaiter& waiter) { return waiter.session.expired(); });
  if (busy_lane_.size() >= core_.options.busy_lane && !make_room(address)) {
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

bool Listener::make_room(std::string_view newcomer) {
  // Choose by what each waiter's session has read (no system call per waiter: a churning flood admits thousands),
  // then look in the chosen one's socket: bytes may have arrived that the loop has not read yet. A waiter that
  // turns out to hold more (a stop) is re-ranked and the choice made again; each is looked at once at most.
  std::vector<LaneWaiter> lane;
  std::vector<bool> looked(busy_lane_.size(), false);
  lane.reserve(busy_lane_.size());
  for (const auto& waiter : busy_lane_) {
    const auto session = waiter.session.lock();
    lane.push_back({waiter.address, session ? session->pending_input(false) : PendingInput::Ordinary});
  }
  for (;;) {
    const auto evict = choose_eviction(lane, newcomer);
    if (!evict) return false;
    const auto session = busy_lane_[*evict].session.lock();
    if (session && !looked[*evict]) {
      looked[*evict] = true;
      if (const auto seen = session->pending_input(true); seen != lane[*evict].input) {
        lane[*evict].input = seen;
        continue;
      }
    }
    if (session) session->close();
    busy_lane_.erase(busy_lane_.begin() + static_cast<std::ptrdiff_t>(*evict));
    return true;
  }
}

}  // namespace rcand::http::detail
