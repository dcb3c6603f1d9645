#include "snapshot_client.hpp"

#include <boost/asio/io_context.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/core/flat_buffer.hpp>
#include <boost/beast/core/tcp_stream.hpp>
#include <boost/beast/http/empty_body.hpp>
#include <boost/beast/http/error.hpp>
#include <boost/beast/http/parser.hpp>
#include <boost/beast/http/read.hpp>
#include <boost/beast/http/string_body.hpp>
#include <boost/beast/http/write.hpp>

#include <openssl/evp.h>

#include <charconv>
#include <vector>

#include "camera_source.hpp"

namespace rcand::plugins::vision {

namespace {

namespace snapshot_net = boost::asio;
namespace snapshot_beast = boost::beast;
namespace snapshot_http = boost::beast::http;
using SnapshotTcp = boost::asio::ip::tcp;

// A failure on a kept-alive connection before any byte of the answer: the camera had closed it while idle.
bool snapshot_stale(const snapshot_beast::error_code& ec) {
  return ec == snapshot_http::error::end_of_stream || ec == snapshot_net::error::eof ||
         ec == snapshot_net::error::connection_reset || ec == snapshot_net::error::broken_pipe ||
         ec == snapshot_net::error::not_connected;
}

std::string basic_credentials(const std::string& userinfo) {
  std::string out(4 * ((userinfo.size() + 2) / 3) + 1, '\0');
  const int length = EVP_EncodeBlock(reinterpret_cast<unsigned char*>(out.data()),
                                     reinterpret_cast<const unsigned char*>(userinfo.data()), static_cast<int>(userinfo.size()));
  out.resize(static_cast<std::size_t>(std::max(length, 0)));
  return "Basic " + out;
}

}  // namespace

std::optional<SnapshotUrl> parse_snapshot_url(std::string_view url, std::string& error) {
  if (url.starts_with("https://")) {
    error = "https is not supported for snapshot cameras (plain http only; use the camera's http:// URL on a trusted network)";
    return std::nullopt;
  }
  if (!url.starts_with("http://")) {
    error = "expected an http:// URL";
    return std::nullopt;
  }
  url.remove_prefix(7);
  if (url.find('#') != std::string_view::npos || url.find_first_of(std::string_view(" \r\n\t\0", 5)) != std::string_view::npos) {
    error = "expected http://[user:password@]host[:port][/path][?query], without a fragment or white space";
    return std::nullopt;
  }
  SnapshotUrl u;
  const auto path_at = url.find_first_of("/?");
  std::string_view authority = url.substr(0, path_at);
  u.target = path_at == std::string_view::npos ? "/" : std::string(url.substr(path_at));
  if (u.target.front() == '?') u.target.insert(0, "/");
  if (const auto at = authority.rfind('@'); at != std::string_view::npos) {
    u.userinfo = std::string(authority.substr(0, at));
    authority.remove_prefix(at + 1);
  }
  std::string_view port;
  if (!authority.empty() && authority.front() == '[') {  // an IPv6 literal
    const auto close = authority.find(']');
    if (close == std::string_view::npos || (close + 1 < authority.size() && authority[close + 1] != ':')) {
      error = "expected [address]:port for an IPv6 host";
      return std::nullopt;
    }
    u.host = std::string(authority.substr(1, close - 1));
    if (close + 1 < authority.size()) port = authority.substr(close + 2);
  } else {
    const auto colon = authority.rfind(':');
    u.host = std::string(authority.substr(0, colon));
    if (colon != std::string_view::npos) port = authority.substr(colon + 1);
  }
  if (u.host.empty()) {
    error = "the URL names no host";
    return std::nullopt;
  }
  if (!port.empty()) {
    unsigned number = 0;
    const auto [end, ec] = std::from_chars(port.data(), port.data() + port.size(), number);
    if (ec != std::errc() || end != port.data() + port.size() || number == 0 || number > 65535) {
      error = "the port must be a number in 1..65535";
      return std::nullopt;
    }
    u.port = static_cast<std::uint16_t>(number);
  }
  return u;
}

struct SnapshotClient::Impl {
  std::string shown;  // the URL as faults name it (no credentials)
  SnapshotUrl url;
  SnapshotLimits limits;
  snapshot_net::io_context io{1};
  std::optional<snapshot_beast::tcp_stream> stream;  // engaged while connected
  snapshot_beast::flat_buffer buffer;
  snapshot_http::request<snapshot_http::empty_body> request;
  std::uint64_t connections = 0;

  [[noreturn]] void fail(const std::string& why) const { throw SourceError("snapshot " + shown + ": " + why); }

  std::string authority() const {
    const bool v6 = url.host.find(':') != std::string::npos;
    return (v6 ? "[" + url.host + "]" : url.host) + ":" + std::to_string(url.port);
  }

  void disconnect() noexcept {
    if (!stream) return;
    snapshot_beast::error_code ignored;
    stream->socket().shutdown(SnapshotTcp::socket::shutdown_both, ignored);
    stream->close();
    stream.reset();
    buffer.consume(buffer.size());
  }

  // Runs the loop until the operation started by `start` completes; the stream's deadline bounds every operation.
  template <class Start> snapshot_beast::error_code run(Start&& start) {
    snapshot_beast::error_code result = snapshot_net::error::would_block;
    io.restart();
    start([&result](snapshot_beast::error_code ec, auto&&...) { result = ec; });
    io.run();
    return result;
  }

  std::vector<SnapshotTcp::endpoint> resolve() {
    snapshot_beast::error_code ec;
    const auto address = snapshot_net::ip::make_address(url.host, ec);
    if (!ec) return {SnapshotTcp::endpoint{address, url.port}};
    // The resolver has no deadline of its own: the loop runs only until ours, then the lookup is cancelled.
    SnapshotTcp::resolver resolver(io);
    std::optional<SnapshotTcp::resolver::results_type> results;
    io.restart();
    resolver.async_resolve(url.host, std::to_string(url.port),
                           [&](snapshot_beast::error_code resolve_ec, SnapshotTcp::resolver::results_type found) {
                             ec = resolve_ec;
                             results = std::move(found);
                           });
    io.run_for(limits.connect_timeout);
    if (!results) {
      resolver.cancel();
      io.restart();
      io.run();
      fail("cannot resolve host '" + url.host + "' within " + std::to_string(limits.connect_timeout.count()) + " ms");
    }
    if (ec || results->empty())
      fail("cannot resolve host '" + url.host + "': " + (ec ? ec.message() : std::string("no address")));
    std::vector<SnapshotTcp::endpoint> endpoints;
    for (const auto& entry : *results) endpoints.push_back(entry.endpoint());
    return endpoints;
  }

  void connect() {
    const auto endpoints = resolve();
    stream.emplace(io);
    ++connections;
    stream->expires_after(limits.connect_timeout);
    const auto ec = run([&](auto handler) { stream->async_connect(endpoints, handler); });
    if (ec) {
      disconnect();
      if (ec == snapshot_beast::error::timeout)
        fail("cannot connect to " + authority() + " within " + std::to_string(limits.connect_timeout.count()) + " ms");
      fail("cannot connect to " + authority() + ": " + ec.message());
    }
    snapshot_beast::error_code ignored;
    stream->socket().set_option(SnapshotTcp::no_delay(true), ignored);
  }

  std::string describe(const snapshot_beast::error_code& ec) const {
    if (ec == snapshot_beast::error::timeout) return "no answer within " + std::to_string(limits.timeout.count()) + " ms";
    if (ec == snapshot_http::error::body_limit)
      return "the answer is larger than " + std::to_string(limits.max_bytes / 1024) + " KiB (snapshot_max_kib)";
    if (snapshot_stale(ec)) return "connection closed by the camera (" + ec.message() + ")";
    return "bad answer: " + ec.message();
  }

  std::shared_ptr<const std::string> fetch() {
    for (int attempt = 0;; ++attempt) {
      const bool reused = stream.has_value();
      if (!reused) connect();
      stream->expires_after(limits.timeout);
      auto ec = run([&](auto handler) { snapshot_http::async_write(*stream, request, handler); });
      snapshot_http::response_parser<snapshot_http::string_body> parser;
      parser.body_limit(limits.max_bytes);
      // The header first: Beast 1.74's eager async_read loses the body_limit error of an over-long Content-Length.
      if (!ec) ec = run([&](auto handler) { snapshot_http::async_read_header(*stream, buffer, parser, handler); });
      if (!ec && !parser.is_done()) ec = run([&](auto handler) { snapshot_http::async_read(*stream, buffer, parser, handler); });
      if (ec) {
        const bool nothing_received = !parser.got_some();
        disconnect();
        if (reused && attempt == 0 && nothing_received && snapshot_stale(ec)) continue;
        fail(describe(ec));
      }
      auto message = parser.release();
      if (!message.keep_alive()) disconnect();
      if (message.result() != snapshot_http::status::ok) {
        const auto reason = message.reason();
        const auto known = snapshot_http::obsolete_reason(message.result());
        fail(std::to_string(message.result_int()) + " " +
             std::string(reason.empty() ? known.data() : reason.data(), reason.empty() ? known.size() : reason.size()));
      }
      return std::make_shared<const std::string>(std::move(message.body()));
    }
  }
};

SnapshotClient::SnapshotClient(const std::string& url, SnapshotLimits limits) : impl_(std::make_unique<Impl>()) {
  Impl& impl = *impl_;
  impl.shown = redact_url(url);
  std::string error;
  auto parsed = parse_snapshot_url(url, error);
  if (!parsed) impl.fail(error);
  impl.url = std::move(*parsed);
  impl.limits = limits;
  impl.request.version(11);
  impl.request.method(snapshot_http::verb::get);
  impl.request.target(impl.url.target);
  const bool plain_host = impl.url.port == 80 && impl.url.host.find(':') == std::string::npos;
  impl.request.set(snapshot_http::field::host, plain_host ? impl.url.host : impl.authority());
  impl.request.set(snapshot_http::field::user_agent, "rcand");
  impl.request.set(snapshot_http::field::accept, "image/jpeg");
  if (!impl.url.userinfo.empty()) impl.request.set(snapshot_http::field::authorization, basic_credentials(impl.url.userinfo));
  impl.request.keep_alive(true);
}

SnapshotClient::~SnapshotClient() { impl_->disconnect(); }

std::shared_ptr<const std::string> SnapshotClient::fetch() { return impl_->fetch(); }

std::uint64_t SnapshotClient::connections() const noexcept { return impl_->connections; }

}  // namespace rcand::plugins::vision
