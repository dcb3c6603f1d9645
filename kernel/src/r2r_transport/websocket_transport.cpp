#include "rcand/kernel/r2r_transport/websocket_transport.hpp"

#include "io_loop.hpp"

#include <boost/asio/executor_work_guard.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/post.hpp>
#include <boost/beast/core/buffers_to_string.hpp>
#include <boost/beast/websocket.hpp>
#include <spdlog/spdlog.h>

#include <deque>
#include <map>
#include <mutex>
#include <set>
#include <shared_mutex>
#include <thread>

#include "rcand/kernel/http/upgrade.hpp"
#include "rcand/kernel/r2r_transport/message_peek.hpp"

namespace rcand::kernel::r2r {

namespace net = boost::asio;
namespace beast = boost::beast;
namespace websocket = boost::beast::websocket;
using tcp = net::ip::tcp;
using Clock = std::chrono::steady_clock;

namespace {

class Connection;

std::string endpoint_text(const tcp::endpoint& endpoint) {
  const auto address = endpoint.address();
  return (address.is_v6() ? "[" + address.to_string() + "]" : address.to_string()) + ":" + std::to_string(endpoint.port());
}

}  // namespace

struct WebSocketTransport::Hub : std::enable_shared_from_this<Hub> {
  Hub(WebSocketOptions options_in, const Authenticator& authenticator_in, std::shared_ptr<spdlog::logger> log_in)
      : options(std::move(options_in)), authenticator(authenticator_in),
        log(log_in ? std::move(log_in) : options.log ? options.log : spdlog::default_logger()) {}

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
  std::size_t inbound = 0;
  WebSocketCounters counters;

  // Dialed connections run here, never on the HTTP server's I/O threads.
  net::io_context client_ioc{1};
  std::optional<net::executor_work_guard<net::io_context::executor_type>> client_work;
  std::thread client_thread;

  void deliver_message(InboundMessage message) {
    std::shared_lock lock(deliver_mutex);
    if (!deliver) return;
    deliver(std::move(message));
  }
  void bind_name(const std::string& name, const std::shared_ptr<Connection>& connection);
  void closed(const std::shared_ptr<Connection>& connection, bool dial_failed, bool oversize);
  std::shared_ptr<Connection> dial_locked(const swarm::SwarmNode& node);
  const swarm::SwarmNode* dial_peer(const std::string& name) const {
    if (name == options.self_name) return nullptr;
    for (const auto& node : options.dial_peers)
      if (node.name == name) return &node;
    return nullptr;
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

  Connection(std::weak_ptr<Hub> hub, Stream stream, Direction direction, std::string peer,
             std::optional<Principal> principal, const WebSocketOptions& options)
      : hub_(std::move(hub)), ws_(std::move(stream)), direction_(direction), peer_(std::move(peer)),
        principal_(std::move(principal)), max_queued_(options.max_queued_bytes) {
    ws_.read_message_max(options.max_message_bytes);
    idle_timeout_ = options.idle_timeout;
    handshake_timeout_ = options.handshake_timeout;
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
      self->opened();
    });
  }

  // Outbound: resolves, connects and upgrades with the peer's token, then flushes the queue and reads.
  void dial(const swarm::SwarmNode& node) {
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
    net::post(ws_.get_executor(), [self = shared_from_this(), bytes = std::move(bytes)]() mutable {
      self->enqueue(std::move(bytes));
    });
  }
  void close() {
    net::post(ws_.get_executor(), [self = shared_from_this()] { self->shut(); });
  }

  Direction direction() const noexcept { return direction_; }
  const std::string& peer() const noexcept { return peer_; }
  std::size_t queued_bytes() const noexcept { return queued_bytes_.load(std::memory_order_relaxed); }
  std::string name_;  // the robot this connection reaches (guarded by Hub::mutex)

 private:
  void on_resolved(beast::error_code ec, tcp::resolver::results_type results) {
    if (closed_) return;
    if (ec || results.empty()) {
      if (fallback_ip_) {  // notes §9: the static ip when the host does not resolve
        beast::error_code parse_ec;
        const auto address = net::ip::make_address(*fallback_ip_, parse_ec);
        if (!parse_ec) {
          const tcp::endpoint endpoint{address, port_};
          peer_ = endpoint_text(endpoint);
          beast::get_lowest_layer(ws_).async_connect(endpoint, [self = shared_from_this()](beast::error_code connect_ec) {
            self->on_connected(connect_ec);
          });
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
    if (!hub || closed_) return;
    {
      std::lock_guard lock(hub->mutex);
      ++hub->counters.frames_in;
    }
    // Transports do not interpret R2R; the announced source_id only makes this connection addressable.
    if (const auto peek = peek_message(bytes); !peek.source_id.empty()) hub->bind_name(peek.source_id, shared_from_this());
    InboundMessage message;
    message.bytes = std::move(bytes);
    message.transport = "ws";
    message.peer = peer_;
    message.principal = principal_;
    message.reply = [weak = weak_from_this()](std::string answer) {
      if (auto self = weak.lock()) self->send(std::move(answer));
    };
    hub->deliver_message(std::move(message));
    read();
  }

  void enqueue(std::string bytes) {
    if (closed_) return;
    if (queued_bytes_ + bytes.size() > max_queued_) {  // a peer that does not read: drop it, not our memory
      if (auto hub = hub_.lock()) hub->log->warn("r2r ws: {} is not reading ({} bytes queued); closing", peer_, queued_bytes_.load());
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
      if (oversize)
        hub->log->info("r2r ws: {} sent a message over {} bytes; closed with 1009", peer_, ws_.read_message_max());
      else if (!quiet)
        hub->log->debug("r2r ws: {} {}: {}", peer_, what, ec.message());
    }
    // Beast has already sent the close frame (1009 for an oversize message); drop the socket.
    shut(oversize);
  }

  void shut(bool oversize = false) {
    if (closed_) return;
    closed_ = true;
    if (resolver_) resolver_->cancel();
    auto& lowest = beast::get_lowest_layer(ws_);
    if (open_ && ws_.is_open()) {
      // A clean close when we can (the peer learns we are going away); the socket goes when it completes or times out.
      lowest.expires_after(std::chrono::milliseconds(500));
      ws_.async_close(websocket::close_code::going_away, [self = shared_from_this()](beast::error_code) {
        beast::get_lowest_layer(self->ws_).close();
      });
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
  std::size_t max_queued_;
  std::chrono::milliseconds idle_timeout_{30'000}, handshake_timeout_{5'000};
  beast::flat_buffer buffer_;
  std::deque<std::string> queue_;
  std::atomic<std::size_t> queued_bytes_{0};
  bool open_ = false, writing_ = false, closed_ = false;
  // Dial only.
  std::optional<tcp::resolver> resolver_;
  std::string host_;
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
  if (connection->direction() == Connection::Direction::Inbound && inbound > 0) --inbound;
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
  auto connection = std::make_shared<Connection>(weak_from_this(), Stream(client_ioc), Connection::Direction::Outbound,
                                                 node.address(), std::nullopt, options);
  connection->name_ = node.name;
  connections.insert(connection);
  by_name[node.name] = connection;
  ++counters.dialed;
  log->debug("r2r ws: dialing {} at {}", node.name, node.address());
  net::post(client_ioc, [connection, node] { connection->dial(node); });
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
      if (hub->inbound >= hub->options.max_connections) {
        ++hub->counters.inbound_refused;
        verdict.refuse = http::error_response(503, "UNAVAILABLE", "too many R2R connections");
        return verdict;
      }
    }
    // Authenticated like HTTP (notes §3): a bearer token or JWT, or ?token= where a client cannot set headers.
    std::optional<std::string_view> bearer;
    if (auto header = request.header("authorization")) bearer = bearer_token(*header);
    else if (auto token = request.query.find("token"); token != request.query.end()) bearer = token->second;
    const auto now_s =
        std::chrono::duration_cast<std::chrono::seconds>(std::chrono::system_clock::now().time_since_epoch()).count();
    auto outcome = hub->authenticator.authorize(bearer, sdk::Scope::Status, now_s);
    if (auto* failure = std::get_if<AuthError>(&outcome)) {
      hub->log->info("r2r ws: upgrade from {} refused: {} ({})", request.remote, failure->status, failure->message);
      std::lock_guard lock(hub->mutex);
      ++hub->counters.inbound_refused;
      verdict.refuse = http::error_response(failure->status, failure->code, failure->message);
      return verdict;
    }
    verdict.take = [weak, principal = std::get<Principal>(std::move(outcome))](http::Upgraded&& upgraded) {
      auto taker = weak.lock();
      if (!taker) return;
      auto connection = std::make_shared<Connection>(weak, std::move(upgraded.stream), Connection::Direction::Inbound,
                                                     upgraded.request.remote, principal, taker->options);
      {
        std::lock_guard lock(taker->mutex);
        if (taker->stopped) return;  // the connection closes as it goes out of scope
        taker->connections.insert(connection);
        ++taker->inbound;
        ++taker->counters.inbound_accepted;
      }
      taker->log->debug("r2r ws: {} connected as {}", upgraded.request.remote, principal.name);
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
  if (!hub.options.dial_peers.empty()) {
    hub.client_work.emplace(hub.client_ioc.get_executor());
    hub.client_thread = start_io_loop(hub.client_ioc, hub.log, "r2r ws client loop");
  }
}

bool WebSocketTransport::send(const std::string& bytes, const std::optional<std::string>& target_id) {
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
        recipients.push_back(hub.dial_locked(*node));
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
      for (const auto& node : hub.options.dial_peers) {
        if (node.name == hub.options.self_name || hub.by_name.contains(node.name) || hub.in_backoff_locked(node.name))
          continue;
        recipients.push_back(hub.dial_locked(node));
      }
    }
  }
  for (const auto& connection : recipients) connection->send(bytes);
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
    hub.inbound = 0;
  }
  for (const auto& connection : open) {
    try {
      connection->close();
    } catch (...) {  // posting failed (loop gone): the connection dies with its loop
    }
  }
  if (hub.client_thread.joinable()) {
    // Queued after the closes, so they run first; what they leave pending is destroyed with the loop.
    net::post(hub.client_ioc, [&hub] { hub.client_ioc.stop(); });
    hub.client_work.reset();
    hub.client_thread.join();
  }
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

}  // namespace rcand::kernel::r2r
