// Test support (header-only, for chat's unit tests, the integration tests and the bench): a model server on loopback
// port 0 that speaks the OpenAI chat completions or the Ollama /api/chat wire format and does what the test scripts
// for each POST - answer (after a delay), fail with a status, hang, answer garbage, stream without end, echo the
// Authorization header - and records what it saw and when the client went away. Plain blocking sockets with
// Boost.Beast for the HTTP: one thread per connection, all joined by the destructor.
#pragma once

#include <poll.h>
#include <sys/socket.h>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/write.hpp>
#include <boost/beast/core/flat_buffer.hpp>
#include <boost/beast/http/read.hpp>
#include <boost/beast/http/string_body.hpp>
#include <boost/beast/http/write.hpp>
#include <nlohmann/json.hpp>

#include <chrono>
#include <condition_variable>
#include <deque>
#include <functional>
#include <list>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace rcand::plugins::chat::testing {

// Milliseconds from a to b, for the timings the tests read off a server's posts.
inline double ms_between(std::chrono::steady_clock::time_point a, std::chrono::steady_clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

class ScriptedModelServer {
 public:
  using Clock = std::chrono::steady_clock;
  enum class Wire { OpenAI, Ollama };
  struct Script {
    enum class Kind { Answer, Status, Hang, Malformed, Endless, EchoKey };
    Kind kind = Kind::Answer;
    nlohmann::json content;              // Answer: the model's answer (dumped into the message content)
    int status = 500;                    // Status / EchoKey: the HTTP status
    std::chrono::milliseconds delay{0};  // Answer and Status: wait this long first (the client may leave meanwhile)
  };
  static Script answer(nlohmann::json content, std::chrono::milliseconds delay = {}) {
    return {Script::Kind::Answer, std::move(content), 200, delay};
  }
  static Script fail(int status, std::chrono::milliseconds delay = {}) { return {Script::Kind::Status, nullptr, status, delay}; }
  static Script hang() { return {Script::Kind::Hang, nullptr, 0, {}}; }
  static Script malformed() { return {Script::Kind::Malformed, nullptr, 200, {}}; }
  static Script endless() { return {Script::Kind::Endless, nullptr, 200, {}}; }
  static Script echo_key(int status = 401) { return {Script::Kind::EchoKey, nullptr, status, {}}; }

  struct Seen {
    std::string method, target, authorization;
    nlohmann::json body;
    Clock::time_point at;        // the request was read
    Clock::time_point answered;  // the answer (or the failure status) was written; epoch when never
    Clock::time_point closed;    // the client closed the connection while we waited or streamed; epoch when never
  };

  explicit ScriptedModelServer(Wire wire, std::string model = "test-model")
      : wire_(wire), model_(std::move(model)), acceptor_(io_, {boost::asio::ip::make_address("127.0.0.1"), 0}) {
    accept_thread_ = std::thread([this] { accept_loop(); });
  }
  ~ScriptedModelServer() {
    {
      std::lock_guard lock(mutex_);
      stopping_ = true;
      for (auto* socket : sockets_) {
        boost::system::error_code ec;
        socket->shutdown(boost::asio::ip::tcp::socket::shutdown_both, ec);
      }
    }
    changed_.notify_all();
    boost::system::error_code ec;
    acceptor_.cancel(ec);
    ::shutdown(acceptor_.native_handle(), SHUT_RDWR);
    acceptor_.close(ec);
    accept_thread_.join();
    for (auto& t : connections_) t.join();
  }

  std::uint16_t port() const { return acceptor_.local_endpoint().port(); }
  // The base URL a brain is configured with.
  std::string url() const { return "http://127.0.0.1:" + std::to_string(port()) + (wire_ == Wire::OpenAI ? "/v1" : ""); }

  // Every POST gets `script` unless one was queued with then().
  void always(Script script) {
    std::lock_guard lock(mutex_);
    default_ = std::move(script);
  }
  void then(Script script) {
    std::lock_guard lock(mutex_);
    queued_.push_back(std::move(script));
  }
  void health_fails(bool fails) {
    std::lock_guard lock(mutex_);
    health_fails_ = fails;
  }

  std::vector<Seen> posts() const {
    std::lock_guard lock(mutex_);
    return posts_;
  }
  std::size_t gets() const {
    std::lock_guard lock(mutex_);
    return gets_;
  }
  // Waits until `n` POSTs were read / `n` clients left mid-wait (false on timeout: a test failure, not a pause).
  bool wait_for_posts(std::size_t n, std::chrono::milliseconds timeout = std::chrono::seconds(10)) {
    std::unique_lock lock(mutex_);
    return changed_.wait_for(lock, timeout, [&] { return posts_.size() >= n; });
  }
  bool wait_for_closes(std::size_t n, std::chrono::milliseconds timeout = std::chrono::seconds(10)) {
    std::unique_lock lock(mutex_);
    return changed_.wait_for(lock, timeout, [&] { return closes_ >= n; });
  }

 private:
  using tcp = boost::asio::ip::tcp;
  void accept_loop() {
    for (;;) {
      auto socket = std::make_unique<tcp::socket>(io_);
      boost::system::error_code ec;
      acceptor_.accept(*socket, ec);
      std::lock_guard lock(mutex_);
      if (ec || stopping_) return;
      sockets_.push_back(socket.get());
      connections_.emplace_back([this, s = std::move(socket)]() mutable { serve(std::move(s)); });
    }
  }

  // Waits up to `wait` for the client to leave (the socket turns readable at EOF); true when it left.
  bool client_left(tcp::socket& socket, std::chrono::milliseconds wait) {
    const auto until = Clock::now() + wait;
    for (;;) {
      {
        std::lock_guard lock(mutex_);
        if (stopping_) return true;
      }
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(until - Clock::now());
      if (wait.count() >= 0 && left.count() <= 0) return false;
      pollfd p{socket.native_handle(), POLLIN, 0};
      const int slice = wait.count() < 0 ? 50 : static_cast<int>(std::min<long long>(50, left.count()));
      if (::poll(&p, 1, slice) > 0) {
        char byte;
        if (::recv(socket.native_handle(), &byte, 1, MSG_PEEK | MSG_DONTWAIT) <= 0) return true;
      }
    }
  }

  std::string envelope(const std::string& content) const {
    if (wire_ == Wire::OpenAI)
      return nlohmann::json{
          {"id", "chatcmpl-1"},
          {"object", "chat.completion"},
          {"model", model_},
          {"choices", {{{"index", 0}, {"message", {{"role", "assistant"}, {"content", content}}}, {"finish_reason", "stop"}}}}}
          .dump();
    return nlohmann::json{{"model", model_}, {"message", {{"role", "assistant"}, {"content", content}}}, {"done", true}}.dump();
  }

  void serve(std::unique_ptr<tcp::socket> socket) {
    namespace http = boost::beast::http;
    boost::beast::flat_buffer buffer;
    http::request<http::string_body> request;
    boost::system::error_code ec;
    http::read(*socket, buffer, request, ec);
    if (ec) return forget(socket.get());
    http::response<http::string_body> response{http::status::ok, 11};
    response.set(http::field::content_type, "application/json");
    response.keep_alive(false);
    if (request.method() == http::verb::get) {
      bool fails;
      {
        std::lock_guard lock(mutex_);
        ++gets_;
        fails = health_fails_;
      }
      if (fails) response.result(http::status::service_unavailable);
      response.body() = wire_ == Wire::OpenAI ? nlohmann::json{{"data", {{{"id", model_}}}}}.dump()
                                              : nlohmann::json{{"models", {{{"name", model_ + ":latest"}}}}}.dump();
      response.prepare_payload();
      http::write(*socket, response, ec);
      return forget(socket.get());
    }
    Script script;
    std::size_t index;
    {
      std::lock_guard lock(mutex_);
      script = queued_.empty() ? default_ : queued_.front();
      if (!queued_.empty()) queued_.pop_front();
      Seen seen;
      seen.method = std::string(request.method_string());
      seen.target = std::string(request.target());
      seen.authorization = std::string(request[http::field::authorization]);
      seen.body = nlohmann::json::parse(request.body(), nullptr, false);
      seen.at = Clock::now();
      posts_.push_back(std::move(seen));
      index = posts_.size() - 1;
    }
    changed_.notify_all();
    const auto mark = [&](Clock::time_point Seen::*field) {
      {
        std::lock_guard lock(mutex_);
        posts_[index].*field = Clock::now();
        if (field == &Seen::closed) ++closes_;
      }
      changed_.notify_all();
    };
    using Kind = Script::Kind;
    if (script.kind == Kind::Hang) {
      if (client_left(*socket, std::chrono::milliseconds(-1))) mark(&Seen::closed);
      return forget(socket.get());
    }
    if ((script.kind == Kind::Answer || script.kind == Kind::Status) && script.delay.count() > 0 &&
        client_left(*socket, script.delay)) {
      mark(&Seen::closed);
      return forget(socket.get());
    }
    if (script.kind == Kind::Endless) {
      // A chunked answer that never ends: chunks until the client leaves.
      const std::string head = "HTTP/1.1 200 OK\r\nContent-Type: application/json\r\nTransfer-Encoding: chunked\r\n\r\n";
      boost::asio::write(*socket, boost::asio::buffer(head), ec);
      const std::string chunk = "400\r\n" + std::string(1024, ' ') + "\r\n";
      while (!ec) boost::asio::write(*socket, boost::asio::buffer(chunk), ec);
      mark(&Seen::closed);
      return forget(socket.get());
    }
    switch (script.kind) {
      case Kind::Answer: response.body() = envelope(script.content.dump()); break;
      case Kind::Malformed: response.body() = envelope("this is not JSON {"); break;
      case Kind::EchoKey:
        response.result(static_cast<unsigned>(script.status));
        response.body() =
            nlohmann::json{{"error", {{"message", "bad key: " + std::string(request[http::field::authorization])}}}}.dump();
        break;
      default:
        response.result(static_cast<unsigned>(script.status));
        response.body() = nlohmann::json{{"error", {{"message", "scripted failure " + std::to_string(script.status)}}}}.dump();
    }
    response.prepare_payload();
    http::write(*socket, response, ec);
    mark(&Seen::answered);
    forget(socket.get());
  }

  void forget(tcp::socket* socket) {
    std::lock_guard lock(mutex_);
    sockets_.remove(socket);
  }

  const Wire wire_;
  const std::string model_;
  boost::asio::io_context io_;
  tcp::acceptor acceptor_;
  std::thread accept_thread_;
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  bool stopping_ = false;
  bool health_fails_ = false;
  Script default_ = answer({{"reply", "ok"}, {"action", nullptr}, {"confidence", 0.5}});
  std::deque<Script> queued_;
  std::vector<Seen> posts_;
  std::size_t gets_ = 0, closes_ = 0;
  std::list<tcp::socket*> sockets_;
  std::list<std::thread> connections_;
};

}  // namespace rcand::plugins::chat::testing
