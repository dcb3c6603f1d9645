#include "libs/swarm/fan_out.hpp"

#include <netdb.h>
#include <pthread.h>
#include <sys/socket.h>

#include <boost/asio/connect.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/ssl/error.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/beast/core/error.hpp>
#include <boost/beast/core/flat_buffer.hpp>
#include <boost/beast/http/parser.hpp>
#include <boost/beast/http/read.hpp>
#include <boost/beast/http/string_body.hpp>
#include <boost/beast/http/write.hpp>

#include <algorithm>
#include <future>
#include <map>
#include <mutex>
#include <thread>
#include <utility>

#include "libs/base/stop_path_priority.hpp"
#include "libs/base/worker_thread.hpp"
#include "libs/http/connection_stream.hpp"
#include "libs/http/tls_context.hpp"
#include "libs/swarm/node_tls.hpp"

namespace rcand::swarm {

PeerRequest peer_request(const SwarmNode& node, std::string method, std::string target, std::string body) {
  PeerRequest request;
  request.name = node.name;
  request.host = node.host;
  request.fallback_ip = node.ip;
  request.port = node.port;
  request.method = std::move(method);
  request.target = std::move(target);
  request.body = std::move(body);
  request.headers = {{"Authorization", "Bearer " + node.token}};
  request.tls = node_tls_settings(node);
  return request;
}

namespace net = boost::asio;
namespace beast = boost::beast;
namespace bhttp = boost::beast::http;
using net::ip::tcp;
using Clock = std::chrono::steady_clock;

// A kept-alive connection to a peer, idle since `since`. Reused for the next request to the same address: a swarm
// broadcasts to the same peers again and again, and a connection that is already open costs the peer no accept.
struct IdleConnection {
  std::unique_ptr<http::ConnectionStream> stream;
  std::chrono::steady_clock::time_point since;
};

// Owned by the FanOut (and kept alive by helper threads still about to post). Pending handlers in `io` hold the
// PeerOps and the PeerOps only point at the loop: no cycle, so destroying the loop after stop() frees them all.
struct FanOut::Loop : std::enable_shared_from_this<FanOut::Loop> {
  // The thread "swarm.deadline": the runs' deadline timers and nothing else, so they fire on time however much I/O
  // the fan-out thread has queued. Declared first: runs held by the fan-out thread's pending handlers own timers on it.
  WorkerThread deadlines{"swarm.deadline", nullptr};
  // The thread "swarm.fanout"; declared before the connections below, so they are closed before its io_context goes.
  WorkerThread worker{"swarm.fanout", nullptr};
  net::io_context& io = worker.context();
  std::shared_ptr<HostResolver> resolver;                   // may be null: getaddrinfo for every host
  std::map<std::string, std::vector<IdleConnection>> idle;  // by "ip:port" ("https://ip:port"); the loop thread's only
  // TLS contexts by their files (and the files' times, so a renewed CA is read again); the loop thread's only.
  std::map<std::string, std::shared_ptr<net::ssl::context>> tls_contexts;
  std::mutex mutex;  // guards `alive` against helper threads posting after stop()
  bool alive = true;

  // Posts `fn` unless the loop was stopped (then it is dropped).
  template <class Fn> void post(Fn&& fn) {
    std::lock_guard lock(mutex);
    if (alive) net::post(io, std::forward<Fn>(fn));
  }
  // Arms `timer` (on `deadlines`) unless the loop was stopped.
  template <class Fn> void arm(net::steady_timer& timer, Clock::time_point when, Fn&& fn) {
    std::lock_guard lock(mutex);
    if (!alive) return;
    timer.expires_at(when);
    timer.async_wait(std::forward<Fn>(fn));
  }
};

namespace {

// Well inside rcand's 60 s idle timeout, so a reused connection is rarely one the peer is closing.
constexpr std::chrono::seconds kMaxIdle{20};
constexpr std::size_t kMaxIdlePerPeer = 4;
// What one answer's head may take (Beast's own default, stated), and what is buffered from the socket at a time: with
// the body limit, everything a peer can make this robot hold per connection, whatever it sends.
constexpr std::uint32_t kHeaderLimit = 8 * 1024;
constexpr std::size_t kReadBufferLimit = 16 * 1024;

// A failure on a reused connection before any byte of the answer: the peer had closed it while idle.
bool is_stale(const beast::error_code& ec) {
  return ec == bhttp::error::end_of_stream || ec == net::error::eof || ec == net::error::connection_reset ||
         ec == net::error::broken_pipe || ec == net::error::not_connected || ec == net::ssl::error::stream_truncated;
}

beast::string_view bsv(std::string_view s) noexcept { return {s.data(), s.size()}; }

// The context for `tls`, made once per set of files (and again when one of them changes). Throws http::TlsError.
std::shared_ptr<net::ssl::context> tls_context_for(FanOut::Loop& loop, const http::ClientTlsSettings& tls) {
  std::string key;
  for (const auto* file : {&tls.ca_file, &tls.cert_file, &tls.key_file}) {
    std::error_code ec;
    const auto written = file->empty() ? std::filesystem::file_time_type{} : std::filesystem::last_write_time(*file, ec);
    key += file->string() + '@' + std::to_string(written.time_since_epoch().count()) + '\n';
  }
  auto& context = loop.tls_contexts[key];
  if (!context) context = http::make_client_tls_context(tls);
  return context;
}

std::string endpoint_text(const tcp::endpoint& endpoint) {
  const auto address = endpoint.address();
  return (address.is_v6() ? "[" + address.to_string() + "]" : address.to_string()) + ":" + std::to_string(endpoint.port());
}

// All results of one run. The peers' results arrive on the fan-out thread; the run's deadline timer fires on the
// deadline thread and answers with what is in, however late the fan-out thread is (its sockets' own expiries wait
// behind its other work). `done` runs once, on whichever thread closes the run; a result that arrives later is dropped.
struct Batch {
  Batch(net::io_context& deadline_io, std::size_t size, FanOut::Done done_)
      : results(size), finished(size, false), remaining(size), done(std::move(done_)), deadline(deadline_io) {}
  std::mutex mutex;  // results, finished, remaining, done
  std::vector<PeerResult> results;
  std::vector<bool> finished;
  std::size_t remaining;
  FanOut::Done done;
  net::steady_timer deadline;  // armed once by run(), then touched only by its own handler

  // Records one peer's result; the last one answers.
  void complete(std::size_t index, PeerResult result) {
    FanOut::Done answer;
    std::vector<PeerResult> all;
    {
      std::lock_guard lock(mutex);
      if (!done || finished[index]) return;
      finished[index] = true;
      results[index] = std::move(result);
      if (--remaining != 0) return;
      answer = take(all);
    }
    answer(std::move(all));
  }
  // Every peer still pending failed with `why`; answers now.
  void expire(const std::vector<std::string>& names, double elapsed_ms, const std::string& why) {
    FanOut::Done answer;
    std::vector<PeerResult> all;
    {
      std::lock_guard lock(mutex);
      if (!done) return;
      for (std::size_t i = 0; i < finished.size(); ++i) {
        if (finished[i]) continue;
        results[i].name = names[i];
        results[i].error = why;
        results[i].latency_ms = elapsed_ms;
      }
      answer = take(all);
    }
    answer(std::move(all));
  }

 private:
  FanOut::Done take(std::vector<PeerResult>& all) {
    all = std::move(results);
    return std::exchange(done, nullptr);
  }
};

class PeerOp : public std::enable_shared_from_this<PeerOp> {
 public:
  PeerOp(FanOut::Loop& loop, std::shared_ptr<Batch> batch, std::size_t index, PeerRequest request, Clock::time_point start,
         std::chrono::milliseconds timeout)
      : loop_(&loop),
        batch_(std::move(batch)),
        index_(index),
        request_(std::move(request)),
        start_(start),
        timeout_(timeout),
        deadline_(start + timeout),
        timer_(loop_->io) {}

  void start() {
    boost::system::error_code ec;
    const auto literal = net::ip::make_address(request_.host, ec);
    if (!ec) return connect({tcp::endpoint(literal, request_.port)});
    resolve();
  }

 private:
  // getaddrinfo on a helper thread; the timer bounds the wait so the fallback ip still fits in the deadline.
  void resolve() {
    const auto budget = request_.fallback_ip ? timeout_ / 2 : timeout_;
    timer_.expires_after(budget);
    timer_.async_wait([self = shared_from_this()](const boost::system::error_code& ec) {
      if (!ec) self->resolved({}, "timed out");
    });
    if (loop_->resolver && loop_->resolver->handles(request_.host)) return resolve_with(*loop_->resolver);
    // The helper holds the op weakly: the op lives and dies on the loop thread only.
    std::thread([loop = loop_->shared_from_this(), weak = weak_from_this(), host = request_.host, port = request_.port]() {
      pthread_setname_np(pthread_self(), "swarm.resolve");
      addrinfo hints{};
      hints.ai_family = AF_UNSPEC;
      hints.ai_socktype = SOCK_STREAM;
      addrinfo* found = nullptr;
      const int rc = ::getaddrinfo(host.c_str(), nullptr, &hints, &found);
      std::vector<tcp::endpoint> endpoints;
      for (auto* it = found; rc == 0 && it != nullptr; it = it->ai_next) {
        if (it->ai_family == AF_INET)
          endpoints.emplace_back(net::ip::address_v4(ntohl(reinterpret_cast<sockaddr_in*>(it->ai_addr)->sin_addr.s_addr)), port);
        else if (it->ai_family == AF_INET6) {
          net::ip::address_v6::bytes_type bytes;
          std::memcpy(bytes.data(), reinterpret_cast<sockaddr_in6*>(it->ai_addr)->sin6_addr.s6_addr, bytes.size());
          endpoints.emplace_back(net::ip::address_v6(bytes), port);
        }
      }
      if (found) ::freeaddrinfo(found);
      std::string why = rc == 0 ? "no addresses" : ::gai_strerror(rc);
      loop->post([weak, endpoints = std::move(endpoints), why = std::move(why)]() mutable {
        if (auto self = weak.lock()) self->resolved(std::move(endpoints), std::move(why));
      });
    }).detach();
  }

  // The resolver answers on any thread (or at once, from its cache): always continue on the loop thread.
  void resolve_with(HostResolver& resolver) {
    resolver.resolve(request_.host, [loop = loop_->weak_from_this(), weak = weak_from_this(), port = request_.port](
                                        std::vector<std::string> addresses, std::string why) {
      std::vector<tcp::endpoint> endpoints;
      for (const auto& text : addresses) {
        boost::system::error_code ec;
        const auto address = net::ip::make_address(text, ec);
        if (!ec) endpoints.emplace_back(address, port);
      }
      // Weakly: the resolver is the loop's, and a callback it still holds must not keep the loop alive.
      if (auto live = loop.lock())
        live->post([weak, endpoints = std::move(endpoints), why = std::move(why)]() mutable {
          if (auto self = weak.lock()) self->resolved(std::move(endpoints), std::move(why));
        });
    });
  }

  void resolved(std::vector<tcp::endpoint> endpoints, std::string why) {
    if (resolution_done_) return;
    resolution_done_ = true;
    timer_.cancel();
    if (!endpoints.empty()) return connect(std::move(endpoints));
    if (request_.fallback_ip) {
      boost::system::error_code ec;
      const auto ip = net::ip::make_address(*request_.fallback_ip, ec);
      if (!ec) return connect({tcp::endpoint(ip, request_.port)});
    }
    finish("cannot resolve host '" + request_.host + "': " + why + (request_.fallback_ip ? "" : " (and no ip fallback)"));
  }

  void connect(std::vector<tcp::endpoint> endpoints) {
    result_.address = endpoint_text(endpoints.front());
    endpoints_ = std::move(endpoints);
    if (request_.tls) {
      try {
        tls_ = tls_context_for(*loop_, *request_.tls);
      } catch (const std::exception& e) {
        return finish(e.what());
      }
    }
    if (auto found = loop_->idle.find(pool_key()); found != loop_->idle.end()) {
      auto& pool = found->second;
      while (!pool.empty() && !stream_) {
        IdleConnection idle = std::move(pool.back());
        pool.pop_back();
        if (Clock::now() - idle.since < kMaxIdle) stream_ = std::move(idle.stream);
      }
      if (stream_) {
        reused_ = true;
        stream_->expires_at(deadline_);
        return send();
      }
    }
    fresh_connect();
  }

  // Idle connections are pooled by address and scheme: a plain one never serves a TLS request.
  std::string pool_key() const { return (tls_ ? "https://" : "") + result_.address; }

  void fresh_connect() {
    reused_ = false;
    stream_ = tls_ ? std::make_unique<http::ConnectionStream>(http::TcpStream(loop_->io), tls_)
                   : std::make_unique<http::ConnectionStream>(loop_->io);
    stream_->expires_at(deadline_);
    stream_->next_layer().async_connect(endpoints_,
                                        [self = shared_from_this()](const beast::error_code& ec, const tcp::endpoint& endpoint) {
                                          if (ec) return self->fail("cannot connect to " + self->result_.address, ec);
                                          self->result_.address = endpoint_text(endpoint);
                                          if (self->tls_) return self->handshake();
                                          self->send();
                                        });
  }

  // The peer's certificate must chain to its `ca` and name its `host` (even when reached through the ip fallback).
  void handshake() {
    SSL* ssl = stream_->tls()->native_handle();
    try {
      http::expect_server_name(ssl, request_.tls->server_name.empty() ? request_.host : request_.tls->server_name);
    } catch (const std::exception& e) {
      return finish(e.what());
    }
    stream_->tls()->async_handshake(net::ssl::stream_base::client, [self = shared_from_this()](const beast::error_code& ec) {
      if (!ec) return self->send();
      if (ec == beast::error::timeout) return self->fail("TLS handshake with " + self->result_.address, ec);
      self->finish("TLS handshake with " + self->result_.address +
                   " failed: " + http::tls_failure(self->stream_->tls()->native_handle(), ec));
    });
  }

  void send() {
    bhttp::verb verb = bhttp::string_to_verb(bsv(request_.method));
    message_.method(verb == bhttp::verb::unknown ? bhttp::verb::get : verb);
    message_.target(bsv(request_.target));
    message_.version(11);
    message_.set(bhttp::field::host, bsv(request_.host));
    message_.set(bhttp::field::user_agent, "rcand-swarm");
    for (const auto& [name, value] : request_.headers) message_.set(bsv(name), bsv(value));
    if (!request_.body.empty() && message_.find(bhttp::field::content_type) == message_.end())
      message_.set(bhttp::field::content_type, "application/json");
    message_.body() = request_.body;
    message_.prepare_payload();
    bhttp::async_write(*stream_, message_, [self = shared_from_this()](const beast::error_code& ec, std::size_t) {
      if (ec && self->reused_ && is_stale(ec)) return self->fresh_connect();
      if (ec) return self->fail(self->request_.method + " " + self->request_.target + " on " + self->result_.address, ec);
      self->receive();
    });
  }

  // The header first, on its own: Beast 1.74's eager parse (what async_read sets) loses the body_limit error of a
  // Content-Length over the limit and reads the whole body anyway; read_header reports it.
  void receive() {
    parser_.emplace();
    parser_->header_limit(kHeaderLimit);
    parser_->body_limit(request_.body_limit);
    bhttp::async_read_header(*stream_, buffer_, *parser_, [self = shared_from_this()](const beast::error_code& ec, std::size_t) {
      if (ec && self->reused_ && is_stale(ec) && !self->parser_->got_some()) {
        self->buffer_.clear();
        return self->fresh_connect();  // the peer had closed the idle connection: once more on a new one
      }
      if (ec) return self->fail(self->request_.method + " " + self->request_.target + " on " + self->result_.address, ec);
      self->receive_body();
    });
  }

  void receive_body() {
    bhttp::async_read(*stream_, buffer_, *parser_, [self = shared_from_this()](const beast::error_code& ec, std::size_t) {
      if (ec) return self->fail(self->request_.method + " " + self->request_.target + " on " + self->result_.address, ec);
      auto& response = self->parser_->get();
      self->result_.reachable = true;
      self->result_.status = static_cast<int>(response.result_int());
      self->result_.body = std::move(response.body());
      if (response.keep_alive()) self->keep_idle();
      self->finish({});
    });
  }

  // Back to the pool for the next broadcast (the answer was complete and the peer keeps the connection).
  void keep_idle() {
    auto& pool = loop_->idle[pool_key()];
    if (pool.size() >= kMaxIdlePerPeer || buffer_.size() != 0) return;
    stream_->expires_never();
    pool.push_back({std::move(stream_), Clock::now()});
  }

  void fail(const std::string& what, const beast::error_code& ec) {
    if (ec == beast::error::timeout) finish(what + ": timed out after " + std::to_string(timeout_.count()) + " ms");
    else if (stream_ && stream_->is_tls() && ec.category() == net::error::get_ssl_category())
      finish(what + ": TLS failure: " + http::tls_failure(stream_->tls()->native_handle(), ec));
    else finish(what + ": " + ec.message());
  }

  void finish(std::string error) {
    if (finished_) return;
    finished_ = true;
    result_.name = request_.name;
    result_.error = std::move(error);
    result_.latency_ms = std::chrono::duration<double, std::milli>(Clock::now() - start_).count();
    batch_->complete(index_, std::move(result_));
  }

  FanOut::Loop* loop_;  // outlives this op: see FanOut::Loop
  std::shared_ptr<Batch> batch_;
  std::size_t index_;
  PeerRequest request_;
  Clock::time_point start_;
  std::chrono::milliseconds timeout_;
  Clock::time_point deadline_;
  std::vector<tcp::endpoint> endpoints_;
  std::shared_ptr<net::ssl::context> tls_;  // set: HTTPS
  std::unique_ptr<http::ConnectionStream> stream_;
  net::steady_timer timer_;
  beast::flat_buffer buffer_{kReadBufferLimit};
  bhttp::request<bhttp::string_body> message_;
  std::optional<bhttp::response_parser<bhttp::string_body>> parser_;  // fresh for each attempt
  PeerResult result_;
  bool resolution_done_ = false;
  bool reused_ = false;
  bool finished_ = false;
};

}  // namespace

FanOut::FanOut(std::shared_ptr<HostResolver> resolver, int deadline_priority, int io_priority) : loop_(std::make_shared<Loop>()) {
  loop_->resolver = std::move(resolver);
  if (deadline_priority > 0) loop_->deadlines.post([deadline_priority] { enter_stop_path_priority(deadline_priority); });
  if (io_priority > 0) loop_->worker.post([io_priority] { enter_stop_path_priority(io_priority); });
}

FanOut::~FanOut() { stop(); }

void FanOut::stop() noexcept {
  if (!loop_) return;
  {
    std::lock_guard lock(loop_->mutex);
    loop_->alive = false;
  }
  loop_->deadlines.stop();  // what is in flight is abandoned, never answered
  loop_->worker.stop();
}

void FanOut::run(std::vector<PeerRequest> requests, std::chrono::milliseconds timeout, Done done, Clock::time_point answer_by) {
  const auto start = Clock::now();
  const auto deadline = std::min(start + timeout, answer_by);
  // What a peer still pending at the deadline is told it had: the budget left of `timeout` when answer_by came first.
  const auto budget = std::chrono::duration_cast<std::chrono::milliseconds>(std::max(deadline - start, Clock::duration::zero()));
  if (requests.empty()) return loop_->post([done = std::move(done)] { done({}); });
  auto batch = std::make_shared<Batch>(loop_->deadlines.context(), requests.size(), std::move(done));
  std::vector<std::string> names;
  for (const auto& request : requests) names.push_back(request.name);
  // Armed here, not from the fan-out thread's queue: the deadline holds even when that queue is long.
  loop_->arm(batch->deadline, deadline, [batch, names = std::move(names), start, budget](const boost::system::error_code& ec) {
    if (ec) return;
    const double elapsed = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
    batch->expire(names, elapsed, "timed out after " + std::to_string(budget.count()) + " ms");
  });
  loop_->post([loop = loop_.get(), requests = std::move(requests), batch, start, budget]() mutable {
    for (std::size_t i = 0; i < requests.size(); ++i)
      std::make_shared<PeerOp>(*loop, batch, i, std::move(requests[i]), start, budget)->start();
  });
}

std::vector<PeerResult> FanOut::run_and_wait(std::vector<PeerRequest> requests, std::chrono::milliseconds timeout) {
  auto promise = std::make_shared<std::promise<std::vector<PeerResult>>>();
  auto future = promise->get_future();
  run(std::move(requests), timeout, [promise](std::vector<PeerResult> results) { promise->set_value(std::move(results)); });
  return future.get();
}

}  // namespace rcand::swarm
