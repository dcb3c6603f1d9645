// One HTTP request to a model server and its answer, blocking the calling thread (a chat pool worker) on an
// io_context of the call's own: nothing is shared between brain calls, and a cancel only has to reach this call.
// Boost.Beast does the HTTP, OpenSSL the TLS (peer certificate and host name verified). Every step is bounded: the
// connect (and TLS handshake) by `connect`, the wait for the answer's header by `first_byte`, everything by
// `deadline`; an answer larger than `max_body` (an endless stream) is cut off. The CancelToken closes the socket
// from the cancelling thread's side through a post to this call's io_context, so the connection is gone within
// microseconds of an e-stop, whatever step the call is in.
#pragma once

#include <rcand/sdk/interfaces/brain.hpp>

#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/ssl/context.hpp>
#include <boost/asio/steady_timer.hpp>
#include <boost/beast/core/tcp_stream.hpp>
#include <boost/beast/http/verb.hpp>
#include <boost/beast/ssl/ssl_stream.hpp>

#include <chrono>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace rcand::plugins::chat {

using Clock = std::chrono::steady_clock;

// Where a model server is: "http://127.0.0.1:11434", "https://api.example.com/v1".
struct Endpoint {
  bool tls = false;
  std::string host;       // name or address, without brackets
  std::string port;       // "80" / "443" unless given
  std::string base_path;  // "/v1", or "" - prefixed to every target
};
// The endpoint, or nullopt with `error` saying why (only http and https; no user info, query or fragment).
std::optional<Endpoint> parse_endpoint(std::string_view url, std::string& error);

struct ExchangeLimits {
  std::chrono::milliseconds connect{2000};      // TCP connect and TLS handshake
  std::chrono::milliseconds first_byte{30000};  // request sent -> answer header (a cold model load waits here)
  Clock::time_point deadline;                   // the whole exchange
  std::size_t max_body = 1 << 20;
};

struct ExchangeResult {
  int status = 0;  // the HTTP status; 0 when there was no answer
  std::string body;
  std::string error;       // "" when an answer came (whatever its status)
  bool retryable = false;  // nothing reached the server (resolve or connect failed): another try may succeed
  bool cancelled = false;
};

class HttpExchange {
 public:
  // `tls` is used for https endpoints and must outlive the exchange (one per brain, configured once).
  HttpExchange(const sdk::CancelToken& cancel, boost::asio::ssl::context* tls);
  ~HttpExchange();
  HttpExchange(const HttpExchange&) = delete;
  HttpExchange& operator=(const HttpExchange&) = delete;

  // One request on a fresh connection (closed afterwards). `headers` are added as given (never logged here).
  ExchangeResult run(const Endpoint& endpoint, boost::beast::http::verb method, const std::string& target,
                     const std::string& body, const std::map<std::string, std::string>& headers, const ExchangeLimits& limits);
  // Waits `delay` (a retry's backoff); false when cancelled first.
  bool pause(std::chrono::milliseconds delay);

 private:
  struct Hook;
  template <class Initiate> boost::system::error_code await(Initiate&& initiate);
  template <class Stream>
  ExchangeResult talk(Stream& stream, const Endpoint& endpoint, boost::beast::http::verb method, const std::string& target,
                      const std::string& body, const std::map<std::string, std::string>& headers, const ExchangeLimits& limits,
                      const std::vector<boost::asio::ip::tcp::endpoint>& addresses);
  void close() noexcept;  // on this call's io_context only

  boost::asio::io_context io_;
  boost::asio::ssl::context* tls_context_;
  boost::asio::steady_timer timer_{io_};
  boost::asio::ip::tcp::resolver resolver_{io_};
  std::optional<boost::beast::tcp_stream> plain_;
  std::optional<boost::beast::ssl_stream<boost::beast::tcp_stream>> tls_;
  sdk::CancelToken cancel_;
  std::shared_ptr<Hook> hook_;
};

// A TLS client context that verifies peers against the system's CAs, or `ca_file` when given. Throws
// std::runtime_error naming the file when it cannot be read.
std::unique_ptr<boost::asio::ssl::context> make_tls_context(const std::string& ca_file);

}  // namespace rcand::plugins::chat
