#include "hostile_peers.hpp"

#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <boost/asio/connect.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/asio/write.hpp>
#include <boost/beast/core/flat_buffer.hpp>
#include <boost/beast/core/tcp_stream.hpp>
#include <boost/beast/http/empty_body.hpp>
#include <boost/beast/http/read.hpp>
#include <boost/beast/http/string_body.hpp>
#include <boost/beast/http/write.hpp>

#include <array>
#include <random>
#include <stdexcept>

namespace rcand::test {

namespace net = boost::asio;
namespace beast = boost::beast;
namespace bhttp = boost::beast::http;
using net::ip::tcp;

// Outside the anonymous namespace: HostilePeers::Listener (external linkage) holds one.
enum class Misbehaviour { Sleeper, ByteByByte, Garbage, Chunked, Headers, Rst, Mistyped };

namespace {

constexpr std::array<std::pair<const char*, Misbehaviour>, 7> kServed{{{"sleeper", Misbehaviour::Sleeper},
                                                                       {"byte_by_byte", Misbehaviour::ByteByByte},
                                                                       {"garbage", Misbehaviour::Garbage},
                                                                       {"chunked", Misbehaviour::Chunked},
                                                                       {"headers", Misbehaviour::Headers},
                                                                       {"rst", Misbehaviour::Rst},
                                                                       {"mistyped", Misbehaviour::Mistyped}}};

// One accepted connection and what its peer does to it. Ends (the socket closes) on a write error (the fan-out gave
// up on it) or after `hold`.
class HostileConnection : public std::enable_shared_from_this<HostileConnection> {
 public:
  HostileConnection(tcp::socket socket, Misbehaviour kind, const HostilePeers::Options& options)
      : socket_(std::move(socket)),
        timer_(socket_.get_executor()),
        kind_(kind),
        options_(options),
        until_(std::chrono::steady_clock::now() + options.hold) {}

  void start() {
    if (kind_ == Misbehaviour::Sleeper) {  // never reads: the request stays in the socket
      timer_.expires_at(until_);
      timer_.async_wait([self = shared_from_this()](const boost::system::error_code&) { self->close(); });
      return;
    }
    socket_.async_read_some(net::buffer(request_), [self = shared_from_this()](const boost::system::error_code& ec, std::size_t) {
      if (ec) return self->close();
      self->misbehave();
    });
  }

 private:
  void misbehave() {
    switch (kind_) {
      case Misbehaviour::ByteByByte: out_ = "HTTP/1.1 200 OK\r\nX-Slow: "; return trickle(0);
      case Misbehaviour::Garbage: {
        std::mt19937 random(12345);
        out_.resize(1024);
        for (char& c : out_) c = static_cast<char>(random() & 0xff);
        return write_then_close();
      }
      case Misbehaviour::Chunked:
        out_ = "HTTP/1.1 200 OK\r\nContent-Type: application/json\r\nTransfer-Encoding: chunked\r\n\r\n";
        repeat_ = "1000\r\n" + std::string(4096, 'x') + "\r\n";
        return write_forever();
      case Misbehaviour::Headers:
        out_ = "HTTP/1.1 200 OK\r\n";
        for (int i = 0; i < 4; ++i) repeat_ += "X-Pad: " + std::string(1000, 'h') + "\r\n";
        return write_forever();
      case Misbehaviour::Rst: {
        const linger abort{1, 0};  // close() now sends RST instead of FIN
        ::setsockopt(socket_.native_handle(), SOL_SOCKET, SO_LINGER, &abort, sizeof abort);
        return close();
      }
      case Misbehaviour::Mistyped: {
        const std::string head = "HTTP/1.1 200 OK\r\nContent-Type: application/json\r\nConnection: close\r\n\r\n";
        const std::string open = R"({"status":"stopped","estopped":true,"motors_stopped":"yes","pad":")";
        const std::size_t pad = options_.mistyped_bytes > open.size() + 2 ? options_.mistyped_bytes - open.size() - 2 : 0;
        out_ = head + open + std::string(pad, 'm') + "\"}";
        return write_then_close();
      }
      case Misbehaviour::Sleeper: return;
    }
  }

  void trickle(std::size_t next) {
    if (std::chrono::steady_clock::now() >= until_) return close();
    const char byte = next < out_.size() ? out_[next] : 'a';  // then the header value never ends
    one_byte_ = byte;
    net::async_write(socket_, net::buffer(&one_byte_, 1),
                     [self = shared_from_this(), next](const boost::system::error_code& ec, std::size_t) {
                       if (ec) return self->close();
                       self->timer_.expires_after(self->options_.trickle);
                       self->timer_.async_wait([self, next](const boost::system::error_code& wait) {
                         if (!wait) self->trickle(next + 1);
                       });
                     });
  }

  void write_then_close() {
    net::async_write(socket_, net::buffer(out_), [self = shared_from_this()](const boost::system::error_code&, std::size_t) {
      boost::system::error_code ignored;
      self->socket_.shutdown(tcp::socket::shutdown_send, ignored);
      self->close();
    });
  }

  void write_forever() {
    if (std::chrono::steady_clock::now() >= until_) return close();
    net::async_write(socket_, net::buffer(out_), [self = shared_from_this()](const boost::system::error_code& ec, std::size_t) {
      if (ec) return self->close();
      self->out_ = self->repeat_;
      self->write_forever();
    });
  }

  void close() {
    boost::system::error_code ignored;
    timer_.cancel();
    socket_.close(ignored);
  }

  tcp::socket socket_;
  net::steady_timer timer_;
  Misbehaviour kind_;
  HostilePeers::Options options_;
  std::chrono::steady_clock::time_point until_;
  std::array<char, 4096> request_{};
  std::string out_;
  std::string repeat_;
  char one_byte_ = 0;
};

}  // namespace

struct HostilePeers::Listener {
  Listener(net::io_context& io, const char* name_, Misbehaviour kind_)
      : name(name_), kind(kind_), acceptor(io, tcp::endpoint(net::ip::make_address("127.0.0.1"), 0)) {}
  std::string name;
  Misbehaviour kind;
  tcp::acceptor acceptor;
};

HostilePeers::HostilePeers(Options options) : options_(options) {
  for (const auto& [name, kind] : kServed) {
    listeners_.push_back(std::make_shared<Listener>(io_, name, kind));
    accept_next(listeners_.back());
  }
  // backlog: listen(0) holds one established connection; this process makes it, so the queue is full from then on
  // and the kernel drops every later SYN (a robot whose rcand is wedged and no longer accepts).
  backlog_fd_ = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t size = sizeof address;
  if (backlog_fd_ < 0 || ::bind(backlog_fd_, reinterpret_cast<sockaddr*>(&address), size) != 0 || ::listen(backlog_fd_, 0) != 0 ||
      ::getsockname(backlog_fd_, reinterpret_cast<sockaddr*>(&address), &size) != 0)
    throw std::runtime_error("HostilePeers: cannot listen for the full backlog");
  backlog_port_ = ntohs(address.sin_port);
  for (int i = 0; i < 2; ++i) {  // the first fills the queue (blocking connect); the second's SYN is already dropped
    const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC | (i == 0 ? 0 : SOCK_NONBLOCK), 0);
    if (fd < 0) throw std::runtime_error("HostilePeers: no socket for the backlog");
    backlog_fillers_.push_back(fd);
    if (::connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0 && i == 0)
      throw std::runtime_error("HostilePeers: cannot fill the backlog");
  }
  refused_port_ = refused_port();
  thread_ = std::thread([this] { io_.run(); });
}

HostilePeers::~HostilePeers() {
  io_.stop();
  thread_.join();
  for (const int fd : backlog_fillers_) ::close(fd);
  if (backlog_fd_ >= 0) ::close(backlog_fd_);
}

void HostilePeers::accept_next(const std::shared_ptr<Listener>& listener) {
  listener->acceptor.async_accept([this, listener](const boost::system::error_code& ec, tcp::socket socket) {
    if (ec) return;
    std::make_shared<HostileConnection>(std::move(socket), listener->kind, options_)->start();
    accept_next(listener);
  });
}

std::vector<std::string> HostilePeers::names() {
  std::vector<std::string> all;
  for (const auto& [name, kind] : kServed) all.emplace_back(name);
  all.emplace_back("backlog");
  all.emplace_back("refused");
  return all;
}

std::vector<SwarmEntry> HostilePeers::entries() const {
  std::vector<SwarmEntry> all;
  for (const auto& listener : listeners_)
    all.emplace_back(listener->name, "127.0.0.1", listener->acceptor.local_endpoint().port());
  all.emplace_back("backlog", "127.0.0.1", backlog_port_);
  all.emplace_back("refused", "127.0.0.1", refused_port_);
  return all;
}

namespace {

// One broadcast stop in flight: connect, send, read the whole answer, on the shared client loop.
class BroadcastStopCall : public std::enable_shared_from_this<BroadcastStopCall> {
 public:
  BroadcastStopCall(net::io_context& io, std::uint16_t port, const std::string& token, std::chrono::milliseconds give_up,
                    TimedBroadcast& out)
      : stream_(io), port_(port), give_up_(give_up), out_(out) {
    request_.method(bhttp::verb::post);
    request_.target("/api/stop");
    request_.version(11);
    request_.set(bhttp::field::host, "127.0.0.1");
    request_.set(bhttp::field::authorization, "Bearer " + token);
    request_.set("X-Swarm-Broadcast", "true");
    request_.set(bhttp::field::connection, "close");
    request_.prepare_payload();
    parser_.body_limit(16 * 1024 * 1024);
  }

  void start() {
    start_ = std::chrono::steady_clock::now();
    out_.sent_us = std::chrono::duration_cast<std::chrono::microseconds>(start_.time_since_epoch()).count();
    stream_.expires_after(give_up_);
    stream_.async_connect(tcp::endpoint(net::ip::make_address("127.0.0.1"), port_), [self = shared_from_this()](
                                                                                        const boost::system::error_code& ec) {
      if (ec) return self->fail("connect", ec);
      bhttp::async_write(self->stream_, self->request_, [self](const boost::system::error_code& wec, std::size_t) {
        if (wec) return self->fail("write", wec);
        self->read();
      });
    });
  }

 private:
  void read() {
    bhttp::async_read(stream_, buffer_, parser_, [self = shared_from_this()](const boost::system::error_code& ec, std::size_t) {
      self->out_.ms = self->elapsed();
      if (ec) return self->fail("read", ec);
      self->out_.status = static_cast<int>(self->parser_.get().result_int());
      self->out_.body = std::move(self->parser_.get().body());
      boost::system::error_code ignored;
      self->stream_.socket().close(ignored);
    });
  }

  void fail(const char* what, const boost::system::error_code& ec) {
    out_.ms = elapsed();
    out_.error = std::string(what) + ": " + ec.message();
  }

  double elapsed() const { return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start_).count(); }

  beast::tcp_stream stream_;
  std::uint16_t port_;
  std::chrono::milliseconds give_up_;
  TimedBroadcast& out_;
  std::chrono::steady_clock::time_point start_;
  bhttp::request<bhttp::empty_body> request_;
  beast::flat_buffer buffer_;
  bhttp::response_parser<bhttp::string_body> parser_;
};

}  // namespace

std::vector<TimedBroadcast> concurrent_broadcast_stops(std::uint16_t port, int count, std::chrono::milliseconds give_up,
                                                       const std::string& token) {
  net::io_context io;
  std::vector<TimedBroadcast> results(static_cast<std::size_t>(count));
  for (auto& result : results) std::make_shared<BroadcastStopCall>(io, port, token, give_up, result)->start();
  io.run();
  return results;
}

}  // namespace rcand::test
