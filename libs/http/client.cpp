#include "libs/http/client.hpp"

#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/asio/ssl/error.hpp>
#include <boost/beast/core/flat_buffer.hpp>
#include <boost/beast/core/string.hpp>
#include <boost/beast/http/error.hpp>
#include <boost/beast/http/parser.hpp>
#include <boost/beast/http/read.hpp>
#include <boost/beast/http/string_body.hpp>
#include <boost/beast/http/write.hpp>

#include <algorithm>
#include <optional>
#include <vector>

#include "libs/http/connection_stream.hpp"
#include "libs/http/tls_context.hpp"

namespace rcand::http {

namespace net = boost::asio;
namespace beast = boost::beast;
namespace bhttp = boost::beast::http;
using net::ip::tcp;
using Clock = std::chrono::steady_clock;

namespace {

// Boost 1.74's Beast speaks boost::string_view.
beast::string_view bsv(std::string_view s) noexcept { return {s.data(), s.size()}; }
std::string_view ssv(beast::string_view s) noexcept { return {s.data(), s.size()}; }

constexpr std::uint64_t kResponseBodyLimit = 64ull * 1024 * 1024;

bool is_token(std::string_view text) noexcept {
  if (text.empty()) return false;
  return std::all_of(text.begin(), text.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
           std::string_view{"!#$%&'*+-.^_`|~"}.find(c) != std::string_view::npos;
  });
}

bool is_safe_value(std::string_view value) noexcept {
  return value.find_first_of(std::string_view{"\r\n\0", 3}) == std::string_view::npos;
}

bool is_valid_target(std::string_view target) noexcept {
  if (target.empty()) return false;
  return std::all_of(target.begin(), target.end(), [](char c) {
    auto u = static_cast<unsigned char>(c);
    return u > 0x20 && u != 0x7f;
  });
}

std::string to_lower(std::string_view text) {
  std::string out{text};
  for (char& c : out) {
    if (c >= 'A' && c <= 'Z') c = static_cast<char>(c - 'A' + 'a');
  }
  return out;
}

bool has_header(const std::map<std::string, std::string>& headers, std::string_view name) {
  return std::any_of(headers.begin(), headers.end(), [&](const auto& h) { return beast::iequals(h.first, bsv(name)); });
}

// A failure on a kept-alive connection before any byte of the answer: the server had closed it while idle.
bool is_stale_connection(const beast::error_code& ec) {
  return ec == bhttp::error::end_of_stream || ec == net::error::eof || ec == net::error::connection_reset ||
         ec == net::error::broken_pipe || ec == net::error::not_connected || ec == net::ssl::error::stream_truncated;
}

bool is_tls_error(const beast::error_code& ec) { return ec.category() == net::error::get_ssl_category(); }

}  // namespace

struct Client::Impl {
  std::string host;
  std::uint16_t port;
  std::chrono::milliseconds timeout;
  net::io_context ioc{1};
  std::shared_ptr<net::ssl::context> tls;  // set: HTTPS
  std::string server_name;                 // what the certificate must name
  std::optional<ConnectionStream> stream;  // engaged while connected
  beast::flat_buffer buffer;

  std::string authority() const {
    const bool v6 = host.find(':') != std::string::npos;
    return (v6 ? "[" + host + "]" : host) + ":" + std::to_string(port);
  }

  void disconnect() noexcept {
    if (stream) {
      beast::error_code ignored;
      stream->socket().shutdown(tcp::socket::shutdown_both, ignored);
      stream->close();
      stream.reset();
    }
    buffer.consume(buffer.size());
  }

  // Runs the loop until the operations started by `start` complete. Every operation is on the stream, whose
  // deadline bounds it, so run() cannot outlive the deadline by much.
  template <class Start> beast::error_code run(Start&& start) {
    beast::error_code result = net::error::would_block;
    ioc.restart();
    start([&result](beast::error_code ec, auto&&...) { result = ec; });
    ioc.run();
    return result;
  }

  std::vector<tcp::endpoint> resolve(Clock::time_point deadline, const std::string& timed_out) {
    beast::error_code ec;
    auto address = net::ip::make_address(host, ec);
    if (!ec) return {tcp::endpoint{address, port}};
    // The resolver has no deadline of its own: run the loop only until ours, then cancel.
    tcp::resolver resolver(ioc);
    std::optional<tcp::resolver::results_type> results;
    ioc.restart();
    resolver.async_resolve(host, std::to_string(port), [&](beast::error_code resolve_ec, tcp::resolver::results_type r) {
      ec = resolve_ec;
      results = std::move(r);
    });
    ioc.run_until(deadline);
    if (!results) {
      resolver.cancel();
      ioc.restart();
      ioc.run();
      throw ClientError(timed_out);
    }
    if (ec || results->empty()) {
      throw ClientError("cannot resolve host '" + host + "': " + (ec ? ec.message() : std::string{"no address"}));
    }
    std::vector<tcp::endpoint> endpoints;
    for (const auto& entry : *results) endpoints.push_back(entry.endpoint());
    return endpoints;
  }

  void connect(Clock::time_point deadline, const std::string& timed_out) {
    auto endpoints = resolve(deadline, timed_out);
    if (tls) stream.emplace(TcpStream(ioc), tls);
    else stream.emplace(ioc);
    stream->expires_at(deadline);
    auto ec = run([&](auto handler) { stream->next_layer().async_connect(endpoints, handler); });
    if (ec) {
      disconnect();
      if (ec == beast::error::timeout) throw ClientError(timed_out);
      throw ClientError("cannot connect to " + authority() + ": " + ec.message());
    }
    beast::error_code ignored;
    stream->socket().set_option(tcp::no_delay(true), ignored);
    if (tls) handshake(timed_out);
  }

  // Nothing is sent before the server's certificate is verified.
  void handshake(const std::string& timed_out) {
    SSL* ssl = stream->tls()->native_handle();
    try {
      expect_server_name(ssl, server_name);
    } catch (const TlsError& e) {
      disconnect();
      throw ClientError(e.what());
    }
    auto ec = run([&](auto handler) { stream->tls()->async_handshake(net::ssl::stream_base::client, handler); });
    if (!ec) return;
    const std::string why = tls_failure(ssl, ec);
    disconnect();
    if (ec == beast::error::timeout) throw ClientError(timed_out);
    throw ClientError("TLS handshake with " + authority() + " failed: " + why);
  }
};

Client::Client(std::string host, std::uint16_t port, std::chrono::milliseconds timeout, std::optional<ClientTlsSettings> tls)
    : impl_(std::make_unique<Impl>()) {
  impl_->host = std::move(host);
  impl_->port = port;
  impl_->timeout = timeout;
  if (tls) {
    try {
      impl_->tls = make_client_tls_context(*tls);
    } catch (const TlsError& e) {
      throw ClientError(e.what());
    }
    impl_->server_name = tls->server_name.empty() ? impl_->host : tls->server_name;
  }
}

Client::~Client() {
  if (impl_) impl_->disconnect();
}

Client::Client(Client&&) noexcept = default;
Client& Client::operator=(Client&&) noexcept = default;

ClientResponse Client::request(std::string_view method, std::string_view target, std::string_view body,
                               const std::map<std::string, std::string>& headers) {
  auto& impl = *impl_;
  // Messages name the path only: the query may carry a token.
  const std::string shown_target{target.substr(0, target.find('?'))};
  const std::string prefix = std::string{method} + " " + shown_target + " on " + impl.authority();
  const std::string timed_out = prefix + ": timed out after " + std::to_string(impl.timeout.count()) + " ms";

  if (!is_token(method)) throw ClientError("invalid HTTP method '" + std::string{method} + "'");
  if (!is_valid_target(target)) throw ClientError("invalid request target for " + prefix);
  bhttp::request<bhttp::string_body> request;
  request.version(11);
  if (auto verb = bhttp::string_to_verb(bsv(method)); verb != bhttp::verb::unknown) {
    request.method(verb);
  } else {
    request.method_string(bsv(method));
  }
  request.target(bsv(target));
  for (const auto& [name, value] : headers) {
    if (!is_token(name)) throw ClientError("invalid header name '" + name + "' for " + prefix);
    if (!is_safe_value(value)) throw ClientError("header '" + name + "' holds CR, LF or NUL, for " + prefix);
    request.insert(name, value);
  }
  if (!has_header(headers, "host")) request.set(bhttp::field::host, impl.authority());
  if (!has_header(headers, "user-agent")) request.set(bhttp::field::user_agent, "rcand");
  if (!body.empty() && !has_header(headers, "content-type")) {
    request.set(bhttp::field::content_type, "application/json");
  }
  request.body() = std::string{body};
  request.prepare_payload();
  const bool head = request.method() == bhttp::verb::head;

  const auto deadline = Clock::now() + impl.timeout;
  for (int attempt = 0;; ++attempt) {
    const bool reused = impl.stream.has_value();
    if (!reused) impl.connect(deadline, timed_out);

    impl.stream->expires_at(deadline);
    auto ec = impl.run([&](auto handler) { bhttp::async_write(*impl.stream, request, handler); });
    bhttp::response_parser<bhttp::string_body> parser;
    parser.body_limit(kResponseBodyLimit);
    if (head) parser.skip(true);
    // The header on its own first: Beast 1.74's eager async_read loses the body_limit error of an over-long
    // Content-Length and would read the whole body.
    if (!ec) ec = impl.run([&](auto handler) { bhttp::async_read_header(*impl.stream, impl.buffer, parser, handler); });
    if (!ec && !parser.is_done())
      ec = impl.run([&](auto handler) { bhttp::async_read(*impl.stream, impl.buffer, parser, handler); });

    if (ec) {
      const bool nothing_received = !parser.got_some();
      // TLS 1.3: a server that refuses the client's certificate says so after the client's handshake is done.
      const std::string tls_why = is_tls_error(ec) ? tls_failure(impl.stream->tls()->native_handle(), ec) : "";
      impl.disconnect();
      if (ec == beast::error::timeout) throw ClientError(timed_out);
      if (reused && attempt == 0 && nothing_received && is_stale_connection(ec)) continue;
      if (is_stale_connection(ec)) throw ClientError(prefix + ": connection closed by the server (" + ec.message() + ")");
      if (!tls_why.empty()) throw ClientError(prefix + ": TLS failure: " + tls_why);
      throw ClientError(prefix + ": bad response: " + ec.message());
    }

    auto message = parser.release();
    ClientResponse response;
    response.status = static_cast<int>(message.result_int());
    for (const auto& field : message) {
      auto [it, inserted] = response.headers.try_emplace(to_lower(ssv(field.name_string())), ssv(field.value()));
      if (!inserted) {
        it->second += ", ";
        it->second.append(ssv(field.value()));
      }
    }
    if (!message.keep_alive()) impl.disconnect();
    response.body = std::move(message.body());
    return response;
  }
}

ClientResponse request(const std::string& host, std::uint16_t port, std::string_view method, std::string_view target,
                       std::string_view body, const std::map<std::string, std::string>& headers,
                       std::chrono::milliseconds timeout, std::optional<ClientTlsSettings> tls) {
  Client client(host, port, timeout, std::move(tls));
  if (has_header(headers, "connection")) return client.request(method, target, body, headers);
  auto with_close = headers;
  with_close.emplace("Connection", "close");
  return client.request(method, target, body, with_close);
}

}  // namespace rcand::http
