#include "services/r2r/transports/websocket_transport.hpp"

#include <spdlog/spdlog.h>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/beast/core/buffers_to_string.hpp>
#include <boost/beast/websocket.hpp>

#include <algorithm>
#include <cstdint>
#include <deque>
#include <limits>
#include <map>
#include <mutex>
#include <set>
#include <shared_mutex>

#include "kernel/auth/slots.hpp"
#include "libs/base/bounded_text.hpp"
#include "libs/base/worker_thread.hpp"
#include "libs/http/tls_context.hpp"
#include "libs/http/upgrade.hpp"
#include "libs/swarm/node_tls.hpp"
#include "services/r2r/transports/message_peek.hpp"

namespace rcand::services::r2r {

using namespace rcand::kernel;

namespace net = boost::asio;
namespace beast = boost::beast;
namespace websocket = boost::beast::websocket;
using tcp = net::ip::tcp;
using Clock = std::chrono::steady_clock;

namespace {

class Connection;

// R2R_SLOTS_RESERVED: the code R2R clients have seen since issue 13.
constexpr SlotWords kR2rSlots{"R2R WebSocket connections",
                              "runtime.r2r.ws_max_connections",
                              "runtime.r2r.ws_max_connections_per_principal",
                              "runtime.r2r.ws_max_connections_per_address",
                              "runtime.r2r.ws_reserved_connections",
                              "TOO_MANY_CONNECTIONS",
                              "R2R_SLOTS_RESERVED"};

std::string endpoint_text(const tcp::endpoint& endpoint) {
  const auto address = endpoint.address();
  return (address.is_v6() ? "[" + address.to_string() + "]" : address.to_string()) + ":" + std::to_string(endpoint.port());
}

}  // namespace

struct WebSocketTransport::Hub : std::enable_shared_from_this<Hub> {
  Hub(WebSocketOptions options_in, const Authenticator& authenticator_in, std::shared_ptr<spdlog::logger> log_in)
      : options(std::move(options_in)),
        authenticator(authenticator_in),
        log(log_in        ? std::move(log_in)
            : options.log ? options.log
                          : spdlog::default_logger()) {}

  const WebSocketOptions options;
  const Authenticator& authenticator;
  const std::shared_ptr<spdlog::logger> log;

  // Deliveries take it shared; stop() takes it exclusively, so no Deliver runs once stop() has returned.
  std::shared_mutex deliver_mutex;
  Deliver deliver;

  mutable std::mutex mutex;  // everything below, and Connection::name_
  bool started = false, stopped = false;
  std::set<std::shared_ptr<Connection>> connections;  // the only strong references while open
  std::map<std::string, std::weak_ptr<Connection>> by_name;
  std::map<std::string, Clock::time_point> dial_failed_at;
  // Inbound slots (issue 13 #12, issue 28 #8): kernel/auth/slots.hpp says who counts against which cap.
  SlotTable slots{{options.max_connections, options.reserved_connections, options.max_connections_per_principal,
                   options.max_connections_per_address}};
  WebSocketCounters counters;

  // Dialed connections run here, never on the HTTP server's I/O threads: the thread "r2r.ws.dial", started with
  // the transport when it has peers to dial (under `mutex`; never reset while the Hub lives).
  std::unique_ptr<WorkerThread> dialer;

  void deliver_message(InboundMessage message) {
    std::shared_lock lock(deliver_mutex);
    if (!deliver) return;
    deliver(std::move(message));
  }
  void bind_name(const std::string& name, const std::shared_ptr<Connection>& connection);
  void closed(const std::shared_ptr<Connection>& connection, bool dial_failed, bool oversize);
  std::shared_ptr<Connection> dial_locked(const swarm::SwarmNode& node);
  const swarm::SwarmRegistry* dial_registry() const { return options.dial_peers ? options.dial_peers() : nullptr; }
  const swarm::SwarmNode* dial_peer(const std::string& name) const {
    const swarm::SwarmRegistry* registry = dial_registry();
    return registry == nullptr || name == options.self_name ? nullptr : registry->find(name);
  }
  bool in_backoff_locked(const std::string& name) const {
    const auto it = dial_failed_at.find(name);
    return it != dial_failed_at.end() && Clock::now() - it->second < options.redial_backoff;
  }
};

namespace {

using Hub = WebSocketTransport::Hub;
using Stream = http::UpgradeStream;

// One WebSocket connection, inbound (upgraded by the HTTP server) or dialed. Every member below the public ones runs
// on the stream's executor (one thread), so the queue needs no lock.
class Connection : public std::enable_shared_from_this<Connection> {
 public:
  enum class Direction { Inbound, Outbound };

  Connection(std::weak_ptr<Hub> hub, Stream stream, Direction direction, std::string peer, std::optional<Principal> principal,
             const WebSocketOptions& options)
      : hub_(std::move(hub)),
        ws_(std::move(stream)),
        direction_(direction),
        peer_(std::move(peer)),
        principal_(std::move(principal)),
        trusted_(direction == Direction::Outbound || (principal_ && sdk::role_grants(principal_->role, sdk::Scope::Config))),
        max_queued_(options.max_queued_bytes) {
    ws_.read_message_max(options.max_message_bytes);
    idle_timeout_ = options.idle_timeout;
    handshake_timeout_ = options.handshake_timeout;
  }

  // Inbound: the credential the upgrade was authorized with, checked again while the socket lives (credential_holds).
  void hold_credential(std::string bearer, std::uint64_t generation) {
    bearer_ = std::move(bearer);
    auth_generation_ = generation;
  }

  // Inbound: answers the upgrade, then reads.
  void accept(beast::http::request<beast::http::string_body> request) {
    beast::get_lowest_layer(ws_).expires_never();  // the websocket's own timeouts apply from here
    websocket::stream_base::timeout timeouts{handshake_timeout_, idle_timeout_, true};
    ws_.set_option(timeouts);
    ws_.set_option(websocket::stream_base::decorator(
        [](websocket::response_type& response) { response.set(beast::http::field::server, "rcand"); }));
    ws_.async_accept(request, [self = shared_from_this()](beast::error_code ec) {
      if (ec) return self->fail(ec, "accept");
      self->close_at_expiry();
      self->opened();
    });
  }

  // Outbound: resolves, connects (and for a node with `ca`, makes the TLS handshake: wss), upgrades with the peer's
  // token, then flushes the queue and reads.
  void dial(const swarm::SwarmNode& node) {
    name_of_dial_ = node.name;
    host_ = node.host;
    port_ = node.port;
    fallback_ip_ = node.ip;
    token_ = node.token;
    resolver_.emplace(ws_.get_executor());
    beast::get_lowest_layer(ws_).expires_after(handshake_timeout_);
    resolver_->async_resolve(host_, std::to_string(port_),
                             [self = shared_from_this()](beast::error_code ec, tcp::resolver::results_type results) {
                               self->on_resolved(ec, std::move(results));
                             });
  }

  // Any thread.
  void send(std::string bytes) {
    net::post(ws_.get_executor(),
              [self = shared_from_this(), bytes = std::move(bytes)]() mutable { self->enqueue(std::move(bytes)); });
  }
  void close() {
    net::post(ws_.get_executor(), [self = shared_from_this()] { self->shut(); });
  }

  Direction direction() const noexcept { return direction_; }
  // Whether the peer may see this robot's bearer token: a robot we dialed (we chose it), or a client that
  // authenticated as OWNER or above (a fleet peer). Never a guest or user watching the fleet. Any thread.
  bool trusted_with_secrets() const noexcept { return trusted_.load(std::memory_order_acquire); }
  const std::string& peer() const noexcept { return peer_; }
  std::size_t queued_bytes() const noexcept { return queued_bytes_.load(std::memory_order_relaxed); }
  std::string name_;            // the robot this connection reaches (guarded by Hub::mutex)
  std::shared_ptr<void> slot_;  // inbound: its place in Hub::slots, given back when closed (guarded by Hub::mutex)

 private:
  void on_resolved(beast::error_code ec, tcp::resolver::results_type results) {
    if (closed_) return;
    if (ec || results.empty()) {
      if (fallback_ip_) {  // docs/protocol.md §9: the static ip when the host does not resolve
        beast::error_code parse_ec;
        const auto address = net::ip::make_address(*fallback_ip_, parse_ec);
        if (!parse_ec) {
          const tcp::endpoint endpoint{address, port_};
          peer_ = endpoint_text(endpoint);
          beast::get_lowest_layer(ws_).async_connect(
              endpoint, [self = shared_from_this()](beast::error_code connect_ec) { self->on_connected(connect_ec); });
          return;
        }
      }
      return fail(ec ? ec : net::error::host_not_found, "resolve " + host_);
    }
    beast::get_lowest_layer(ws_).async_connect(
        results, [self = shared_from_this()](beast::error_code connect_ec, const tcp::endpoint& endpoint) {
          self->peer_ = endpoint_text(endpoint);
          self->on_connected(connect_ec);
        });
  }

  void on_connected(beast::error_code ec) {
    if (closed_) return;
    if (ec) return fail(ec, "connect");
    auto* tls = ws_.next_layer().tls();
    if (tls == nullptr) return upgrade();
    try {
      http::expect_server_name(tls->native_handle(), host_);  // SNI, and the name its certificate must carry
    } catch (const http::TlsError& e) {
      return fail_tls(e.what());
    }
    // Still under the dial's deadline: a peer that never answers the handshake is dropped like one that never accepts.
    tls->async_handshake(net::ssl::stream_base::client, [self = shared_from_this()](beast::error_code tls_ec) {
      if (self->closed_) return;
      if (tls_ec == beast::error::timeout) return self->fail_tls("the TLS handshake timed out");
      if (tls_ec) return self->fail_tls(http::tls_failure(self->ws_.next_layer().tls()->native_handle(), tls_ec));
      self->upgrade();
    });
  }

  // A wss dial that failed before the upgrade: the operator's to fix (a CA or certificate), so it is logged as such.
  void fail_tls(const std::string& why) {
    if (auto hub = hub_.lock()) hub->log->warn("r2r ws: TLS with {} at {} failed: {}", name_of_dial_, peer_, why);
    shut();
  }

  void upgrade() {
    beast::get_lowest_layer(ws_).expires_never();
    websocket::stream_base::timeout timeouts{handshake_timeout_, idle_timeout_, true};
    ws_.set_option(timeouts);
    ws_.set_option(websocket::stream_base::decorator([token = token_](websocket::request_type& request) {
      request.set(beast::http::field::authorization, "Bearer " + token);
      request.set(beast::http::field::user_agent, "rcand-r2r");
    }));
    token_.clear();  // the decorator holds its own copy; nothing else keeps the secret
    ws_.async_handshake(host_ + ":" + std::to_string(port_), std::string(kWebSocketPath),
                        [self = shared_from_this()](beast::error_code handshake_ec) {
                          if (handshake_ec) return self->fail(handshake_ec, "upgrade");
                          self->opened();
                        });
  }

  // A socket never outlives its credential (docs/protocol.md §3): an inbound one is closed (1008, policy) once its JWT expires,
  // and re-authorized after a config reload (the next frame in or out), so a token removed by SIGHUP ends it. The
  // principal's role and scopes follow the reload. Returns false when it closed the connection.
  bool credential_holds() {
    if (direction_ != Direction::Inbound || !principal_ || closed_) return !closed_;
    auto hub = hub_.lock();
    if (!hub) return false;
    const std::int64_t now_s =
        std::chrono::duration_cast<std::chrono::seconds>(std::chrono::system_clock::now().time_since_epoch()).count();
    std::string why;
    const char* reason = nullptr;  // the close frame's reason (at most 123 bytes): what the client is told
    if (principal_->expires_s && now_s > *principal_->expires_s) {
      why = "its JWT expired";
      reason = "R2R credential expired (JWT exp); reconnect with a fresh one";
    } else if (const std::uint64_t generation = hub->authenticator.generation(); generation != auth_generation_) {
      auth_generation_ = generation;  // read first: a reload racing this check is caught by the next one
      auto verdict = hub->authenticator.authorize(bearer_, sdk::Scope::Status, now_s);
      if (auto* failure = std::get_if<AuthError>(&verdict)) {
        why = "its credential is no longer accepted: " + failure->message;
        reason = "R2R credential revoked (config reload)";
      } else {
        principal_ = std::get<Principal>(std::move(verdict));
        trusted_.store(sdk::role_grants(principal_->role, sdk::Scope::Config), std::memory_order_release);
      }
    }
    if (why.empty()) return true;
    hub->log->info("r2r ws: {} ({}) closed: {}", peer_, bounded_text(principal_->name, 64), why);
    {
      std::lock_guard lock(hub->mutex);
      ++hub->counters.closed_credentials;
    }
    close_reason_ = websocket::close_reason(websocket::close_code::policy_error, reason);
    shut();
    return false;
  }

  // Arms the expiry timer: at most an hour at a time (exp may be any int64; the wall clock may jump), re-armed
  // while the credential holds.
  void close_at_expiry() {
    if (closed_ || !principal_ || !principal_->expires_s) return;
    constexpr std::int64_t kMaxWaitMs = 3'600'000;
    const std::int64_t now_ms =
        std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::system_clock::now().time_since_epoch()).count();
    const std::int64_t expires_s = *principal_->expires_s;
    // Closed once the whole second after expires_s has begun (credential_holds: now_s > expires_s).
    const std::int64_t left_ms = expires_s >= (std::numeric_limits<std::int64_t>::max() / 1000) - 1
                                     ? kMaxWaitMs
                                     : std::clamp<std::int64_t>((expires_s + 1) * 1000 - now_ms, 0, kMaxWaitMs);
    if (!expiry_) expiry_.emplace(ws_.get_executor());
    expiry_->expires_after(std::chrono::milliseconds(left_ms));
    expiry_->async_wait([self = shared_from_this()](beast::error_code ec) {
      if (!ec && self->credential_holds()) self->close_at_expiry();
    });
  }

  void opened() {
    if (closed_) return;
    open_ = true;
    read();
    write_next();
  }

  void read() {
    ws_.async_read(buffer_, [self = shared_from_this()](beast::error_code ec, std::size_t) {
      if (ec) return self->fail(ec, "read");
      self->on_frame();
    });
  }

  void on_frame() {
    std::string bytes = beast::buffers_to_string(buffer_.data());
    buffer_.consume(buffer_.size());
    auto hub = hub_.lock();
    if (!hub || closed_ || !credential_holds()) return;
    {
      std::lock_guard lock(hub->mutex);
      ++hub->counters.frames_in;
    }
    // Transports do not interpret R2R; the announced source_id only makes this connection addressable (not a
    // relayed message's: that sender is at the far side of the robot at the other end).
    if (const auto peek = peek_message(bytes); !peek.source_id.empty() && !peek.relayed)
      hub->bind_name(peek.source_id, shared_from_this());
    InboundMessage message;
    message.bytes = std::move(bytes);
    message.transport = "ws";
    message.peer = peer_;
    message.principal = principal_;
    message.trusted_with_secrets = trusted_with_secrets();
    message.reply = [weak = weak_from_this()](std::string answer) {
      if (auto self = weak.lock()) self->send(std::move(answer));
    };
    hub->deliver_message(std::move(message));
    read();
  }

  void enqueue(std::string bytes) {
    if (closed_ || !credential_holds()) return;
    if (queued_bytes_ + bytes.size() > max_queued_) {  // a peer that does not read: drop it, not our memory
      if (auto hub = hub_.lock())
        hub->log->warn("r2r ws: {} is not reading ({} bytes queued); closing", peer_, queued_bytes_.load());
      return shut();
    }
    queued_bytes_ += bytes.size();
    queue_.push_back(std::move(bytes));
    if (open_ && !writing_) write_next();
  }

  void write_next() {
    if (closed_ || writing_ || queue_.empty()) return;
    writing_ = true;
    ws_.text(true);
    ws_.async_write(net::buffer(queue_.front()), [self = shared_from_this()](beast::error_code ec, std::size_t) {
      self->writing_ = false;
      if (self->closed_) return;  // shut() owns the queue now
      if (ec) return self->fail(ec, "write");
      self->queued_bytes_ -= self->queue_.front().size();
      self->queue_.pop_front();
      if (auto hub = self->hub_.lock()) {
        std::lock_guard lock(hub->mutex);
        ++hub->counters.frames_out;
      }
      self->write_next();
    });
  }

  void fail(beast::error_code ec, const std::string& what) {
    const bool oversize = ec == websocket::error::message_too_big;
    const bool quiet = closed_ || ec == net::error::operation_aborted || ec == websocket::error::closed ||
                       ec == net::error::eof || ec == beast::error::timeout;
    auto hub = hub_.lock();
    if (hub) {
      if (oversize) hub->log->info("r2r ws: {} sent a message over {} bytes; closed with 1009", peer_, ws_.read_message_max());
      else if (!quiet) hub->log->debug("r2r ws: {} {}: {}", peer_, what, ec.message());
    }
    // Beast has already sent the close frame (1009 for an oversize message); drop the socket.
    shut(oversize);
  }

  void shut(bool oversize = false) {
    if (closed_) return;
    closed_ = true;
    if (resolver_) resolver_->cancel();
    if (expiry_) expiry_->cancel();
    auto& lowest = beast::get_lowest_layer(ws_);
    if (open_ && ws_.is_open()) {
      // A clean close when we can (the peer learns we are going away); the socket goes when it completes or times out.
      lowest.expires_after(std::chrono::milliseconds(500));
      ws_.async_close(close_reason_,
                      [self = shared_from_this()](beast::error_code) { beast::get_lowest_layer(self->ws_).close(); });
    } else {
      lowest.close();
    }
    if (!writing_) queue_.clear();  // a write in flight still reads its front element: it goes with the connection
    queued_bytes_ = 0;
    if (auto hub = hub_.lock()) hub->closed(shared_from_this(), direction_ == Direction::Outbound && !open_, oversize);
  }

  std::weak_ptr<Hub> hub_;
  websocket::stream<Stream> ws_;
  Direction direction_;
  std::string peer_;
  std::optional<Principal> principal_;
  std::atomic<bool> trusted_;          // follows principal_ (a reload may lower its role)
  std::string bearer_;                 // inbound: the credential, to re-authorize after a reload
  std::uint64_t auth_generation_ = 0;  // the authenticator's generation it was last authorized under
  std::optional<net::steady_timer> expiry_;
  websocket::close_reason close_reason_{websocket::close_code::going_away};
  std::size_t max_queued_;
  std::chrono::milliseconds idle_timeout_{30'000}, handshake_timeout_{5'000};
  beast::flat_buffer buffer_;
  std::deque<std::string> queue_;
  std::atomic<std::size_t> queued_bytes_{0};
  bool open_ = false, writing_ = false, closed_ = false;
  // Dial only.
  std::optional<tcp::resolver> resolver_;
  std::string name_of_dial_, host_;
  std::uint16_t port_ = 0;
  std::optional<std::string> fallback_ip_;
  std::string token_;
};

}  // namespace

void Hub::bind_name(const std::string& name, const std::shared_ptr<Connection>& connection) {
  std::lock_guard lock(mutex);
  if (stopped || connection->name_ == name) return;
  if (!connections.contains(connection)) return;  // already closed
  // Which robot is at the other end (broadcasts go once per robot), fixed by its first announcement.
  if (connection->name_.empty()) connection->name_ = name;
  if (connection->name_ != name) return;
  // The first live connection holding a name keeps it; a newcomer cannot take over a robot's traffic.
  auto& slot = by_name[name];
  if (auto holder = slot.lock(); holder && holder != connection) return;
  slot = connection;
}

void Hub::closed(const std::shared_ptr<Connection>& connection, bool dial_failed, bool oversize) {
  std::lock_guard lock(mutex);
  if (connections.erase(connection) == 0) return;
  connection->slot_.reset();
  for (auto it = by_name.begin(); it != by_name.end();) {
    if (auto holder = it->second.lock(); !holder || holder == connection) it = by_name.erase(it);
    else ++it;
  }
  // Another open connection to the same robot (both dialed each other) takes over its name.
  if (!connection->name_.empty() && !by_name.contains(connection->name_))
    for (const auto& other : connections)
      if (other->name_ == connection->name_) {
        by_name[other->name_] = other;
        break;
      }
  if (dial_failed) {
    ++counters.dial_failed;
    if (!connection->name_.empty()) dial_failed_at[connection->name_] = Clock::now();
  }
  if (oversize) ++counters.closed_oversize;
}

std::shared_ptr<Connection> Hub::dial_locked(const swarm::SwarmNode& node) {
  std::optional<Stream> stream;
  if (const auto tls = swarm::node_tls_settings(node)) {
    try {  // read on every dial (dials are rare: a connection stays open), so a renewed CA file is picked up
      stream.emplace(http::TcpStream(dialer->context()), http::make_client_tls_context(*tls));
    } catch (const http::TlsError& e) {  // a missing or unreadable CA, certificate or key: named in the message
      log->error("r2r ws: cannot dial {}: {}", node.name, e.what());
      ++counters.dial_failed;
      dial_failed_at[node.name] = Clock::now();
      return nullptr;
    }
  } else {
    stream.emplace(dialer->context());
  }
  auto connection = std::make_shared<Connection>(weak_from_this(), std::move(*stream), Connection::Direction::Outbound,
                                                 node.address(), std::nullopt, options);
  connection->name_ = node.name;
  connections.insert(connection);
  by_name[node.name] = connection;
  ++counters.dialed;
  log->debug("r2r ws: dialing {} at {}://{}{}", node.name, node.ca ? "wss" : "ws", node.address(), kWebSocketPath);
  net::post(dialer->context(), [connection, node] { connection->dial(node); });
  return connection;
}

WebSocketTransport::WebSocketTransport(WebSocketOptions options, const Authenticator& authenticator)
    : hub_(std::make_shared<Hub>(std::move(options), authenticator, nullptr)) {}

WebSocketTransport::~WebSocketTransport() { stop(); }

http::UpgradeHandler WebSocketTransport::upgrade_handler() {
  return [weak = std::weak_ptr<Hub>(hub_)](const http::Request& request) -> http::UpgradeVerdict {
    if (request.path != kWebSocketPath) return {};
    http::UpgradeVerdict verdict;
    auto hub = weak.lock();
    if (!hub) {
      verdict.refuse = http::error_response(503, "UNAVAILABLE", "R2R is not running");
      return verdict;
    }
    {
      std::lock_guard lock(hub->mutex);
      if (!hub->started || hub->stopped) {
        verdict.refuse = http::error_response(503, "UNAVAILABLE", "R2R is not running");
        return verdict;
      }
      if (hub->slots.in_use() >= hub->options.max_connections) {  // before the credential is checked: full is full
        ++hub->counters.inbound_refused;
        verdict.refuse = http::error_response(503, "UNAVAILABLE", "too many R2R connections");
        return verdict;
      }
    }
    // Authenticated like HTTP (docs/protocol.md §3): a bearer token or JWT, or ?token= where a client cannot set headers.
    std::optional<std::string_view> bearer;
    if (auto header = request.header("authorization")) bearer = bearer_token(*header);
    else if (auto token = request.query.find("token"); token != request.query.end()) bearer = token->second;
    const auto now_s =
        std::chrono::duration_cast<std::chrono::seconds>(std::chrono::system_clock::now().time_since_epoch()).count();
    const std::uint64_t generation = hub->authenticator.generation();  // before: a reload in between is re-checked
    auto outcome = hub->authenticator.authorize(bearer, sdk::Scope::Status, now_s);
    if (auto* failure = std::get_if<AuthError>(&outcome)) {
      hub->log->info("r2r ws: upgrade from {} refused: {} ({})", request.remote, failure->status, failure->message);
      std::lock_guard lock(hub->mutex);
      ++hub->counters.inbound_refused;
      verdict.refuse = http::error_response(failure->status, failure->code, failure->message);
      return verdict;
    }
    const Principal& principal = std::get<Principal>(outcome);
    // Slots (issue 13 #12, issue 28 #8): below OWNER a principal holds at most max_connections_per_principal sockets
    // and one address at most max_connections_per_address (429), and the last reserved_connections slots are the
    // OWNER's and CREATOR's (503), so no guest, nor many guests on one host, can lock an operator out. The slot is the
    // upgrade's from here and the connection's once taken: an upgrade the server drops after this hook gives it back.
    const SlotHolder holder =
        slot_holder(principal.name, principal.role, principal.via == "open", http::client_address(request.remote));
    SlotTable::Claim claim;
    {
      std::lock_guard lock(hub->mutex);
      if (!hub->stopped && hub->started) claim = hub->slots.claim(holder);
      if (!claim.slot) {
        ++hub->counters.inbound_refused;
        if (hub->stopped || !hub->started) verdict.refuse = http::error_response(503, "UNAVAILABLE", "R2R is not running");
        else verdict.refuse = slot_refusal(claim, kR2rSlots, holder, principal.role);
        return verdict;
      }
    }
    auto slot = std::move(claim.slot);
    verdict.take = [weak, principal = std::get<Principal>(std::move(outcome)), credential = std::string(bearer.value_or("")),
                    generation, slot](http::Upgraded&& upgraded) {
      auto taker = weak.lock();
      if (!taker) return;
      auto connection = std::make_shared<Connection>(weak, std::move(upgraded.stream), Connection::Direction::Inbound,
                                                     upgraded.request.remote, principal, taker->options);
      connection->hold_credential(credential, generation);
      {
        std::lock_guard lock(taker->mutex);
        if (taker->stopped) return;  // the connection closes as it goes out of scope
        taker->connections.insert(connection);
        connection->slot_ = slot;  // the connection's now: Hub::closed gives it back
        ++taker->counters.inbound_accepted;
      }
      taker->log->debug("r2r ws: {} connected as {}", upgraded.request.remote, bounded_text(principal.name, 64));
      connection->accept(std::move(upgraded.raw));
    };
    return verdict;
  };
}

void WebSocketTransport::start(Deliver deliver) {
  Hub& hub = *hub_;
  {
    std::unique_lock lock(hub.deliver_mutex);
    hub.deliver = std::move(deliver);
  }
  std::lock_guard lock(hub.mutex);
  if (hub.started) return;
  hub.started = true;
  if (hub.options.dial_peers) hub.dialer = std::make_unique<WorkerThread>("r2r.ws.dial", nullptr);
}

bool WebSocketTransport::send(const std::string& bytes, const std::optional<std::string>& target_id) {
  return send_own(bytes, bytes, target_id);
}

bool WebSocketTransport::send_own(const std::string& with_token, const std::string& open,
                                  const std::optional<std::string>& target_id) {
  Hub& hub = *hub_;
  std::vector<std::shared_ptr<Connection>> recipients;
  {
    std::lock_guard lock(hub.mutex);
    if (!hub.started || hub.stopped) return false;
    if (target_id) {
      if (auto it = hub.by_name.find(*target_id); it != hub.by_name.end())
        if (auto connection = it->second.lock()) recipients.push_back(std::move(connection));
      if (recipients.empty()) {
        const auto* node = hub.dial_peer(*target_id);
        if (node == nullptr || hub.in_backoff_locked(node->name)) return false;
        auto dialed = hub.dial_locked(*node);
        if (!dialed) return false;
        recipients.push_back(std::move(dialed));
      }
    } else {
      for (const auto& connection : hub.connections) {
        // One copy per robot: a robot both connected to us and dialed by us is reached once.
        if (!connection->name_.empty()) {
          auto it = hub.by_name.find(connection->name_);
          if (it != hub.by_name.end() && it->second.lock() != connection) continue;
        }
        recipients.push_back(connection);
      }
      if (const swarm::SwarmRegistry* registry = hub.dial_registry())
        for (const auto& node : registry->nodes) {
          if (node.name == hub.options.self_name || hub.by_name.contains(node.name) || hub.in_backoff_locked(node.name)) continue;
          if (auto dialed = hub.dial_locked(node)) recipients.push_back(std::move(dialed));
        }
    }
  }
  for (const auto& connection : recipients) connection->send(connection->trusted_with_secrets() ? with_token : open);
  return !recipients.empty();
}

void WebSocketTransport::stop() noexcept {
  Hub& hub = *hub_;
  {
    std::unique_lock lock(hub.deliver_mutex);
    hub.deliver = nullptr;
  }
  std::set<std::shared_ptr<Connection>> open;
  {
    std::lock_guard lock(hub.mutex);
    if (hub.stopped) return;
    hub.stopped = true;
    open.swap(hub.connections);
    hub.by_name.clear();
  }
  for (const auto& connection : open) {
    try {
      connection->close();
    } catch (...) {  // posting failed (loop gone): the connection dies with its loop
    }
  }
  // The closes are queued, so they run first; what they leave pending is destroyed with the dialer.
  if (hub.dialer) hub.dialer->stop_after_queued();
}

nlohmann::json WebSocketTransport::connections() const {
  nlohmann::json list = nlohmann::json::array();
  std::lock_guard lock(hub_->mutex);
  for (const auto& connection : hub_->connections)
    list.push_back({{"peer", connection->peer()},
                    {"name", connection->name_.empty() ? nlohmann::json() : nlohmann::json(connection->name_)},
                    {"direction", connection->direction() == Connection::Direction::Inbound ? "inbound" : "outbound"},
                    {"queued_bytes", connection->queued_bytes()}});
  return {{"connections", std::move(list)}};
}

WebSocketCounters WebSocketTransport::counters() const {
  std::lock_guard lock(hub_->mutex);
  return hub_->counters;
}

void apply_websocket_config(const nlohmann::json& r2r_block, WebSocketOptions& options) {
  if (!r2r_block.is_object()) return;
  auto size_key = [&](const char* key, std::size_t& out) {
    if (const auto it = r2r_block.find(key); it != r2r_block.end() && it->is_number_integer() && it->get<std::int64_t>() >= 0)
      out = static_cast<std::size_t>(it->get<std::int64_t>());
  };
  size_key("ws_max_connections", options.max_connections);
  size_key("ws_max_connections_per_principal", options.max_connections_per_principal);
  size_key("ws_max_connections_per_address", options.max_connections_per_address);
  size_key("ws_reserved_connections", options.reserved_connections);
  size_key("ws_max_queued_bytes", options.max_queued_bytes);
}

}  // namespace rcand::services::r2r
