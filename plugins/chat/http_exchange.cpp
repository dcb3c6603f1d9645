#include "http_exchange.hpp"

#include <openssl/ssl.h>
#include <openssl/x509v3.h>
#include <boost/asio/connect.hpp>
#include <boost/asio/post.hpp>
#include <boost/asio/ssl/error.hpp>
#include <boost/beast/core/flat_buffer.hpp>
#include <boost/beast/http/error.hpp>
#include <boost/beast/http/read.hpp>
#include <boost/beast/http/string_body.hpp>
#include <boost/beast/http/write.hpp>
#include <boost/beast/version.hpp>

#include <algorithm>
#include <charconv>
#include <mutex>
#include <stdexcept>
#include <vector>

namespace rcand::plugins::chat {
namespace {

namespace asio = boost::asio;
namespace beast = boost::beast;
namespace http = beast::http;
using boost::system::error_code;
using std::chrono::milliseconds;
using tcp = asio::ip::tcp;

std::string ms_text(milliseconds ms) { return std::to_string(ms.count()) + " ms"; }

}  // namespace

std::optional<Endpoint> parse_endpoint(std::string_view url, std::string& error) {
  Endpoint e;
  if (url.starts_with("https://")) {
    e.tls = true;
    url.remove_prefix(8);
  } else if (url.starts_with("http://")) {
    url.remove_prefix(7);
  } else {
    error = "expected an http:// or https:// URL";
    return std::nullopt;
  }
  const auto slash = url.find('/');
  std::string_view authority = url.substr(0, slash);
  std::string_view path = slash == std::string_view::npos ? std::string_view{} : url.substr(slash);
  if (authority.empty() || authority.find('@') != std::string_view::npos || path.find_first_of("?#") != std::string_view::npos) {
    error = "expected scheme://host[:port][/path], without user info, query or fragment";
    return std::nullopt;
  }
  std::string_view port;
  if (authority.front() == '[') {  // an IPv6 literal
    const auto close = authority.find(']');
    if (close == std::string_view::npos) {
      error = "unclosed [ in the host";
      return std::nullopt;
    }
    e.host = std::string(authority.substr(1, close - 1));
    if (close + 1 < authority.size()) {
      if (authority[close + 1] != ':') {
        error = "expected :port after ]";
        return std::nullopt;
      }
      port = authority.substr(close + 2);
    }
  } else {
    const auto colon = authority.rfind(':');
    e.host = std::string(authority.substr(0, colon));
    if (colon != std::string_view::npos) port = authority.substr(colon + 1);
  }
  if (!port.empty()) {
    unsigned number = 0;
    const auto [end, ec] = std::from_chars(port.data(), port.data() + port.size(), number);
    if (ec != std::errc() || end != port.data() + port.size() || number == 0 || number > 65535) {
      error = "the port must be a number in [1, 65535]";
      return std::nullopt;
    }
  }
  if (e.host.empty()) {
    error = "no host";
    return std::nullopt;
  }
  e.port = port.empty() ? (e.tls ? "443" : "80") : std::string(port);
  while (path.ends_with('/')) path.remove_suffix(1);
  e.base_path = std::string(path);
  return e;
}

std::unique_ptr<asio::ssl::context> make_tls_context(const std::string& ca_file) {
  auto context = std::make_unique<asio::ssl::context>(asio::ssl::context::tls_client);
  context->set_options(asio::ssl::context::default_workarounds | asio::ssl::context::no_sslv2 | asio::ssl::context::no_sslv3 |
                       asio::ssl::context::no_tlsv1 | asio::ssl::context::no_tlsv1_1);
  context->set_verify_mode(asio::ssl::verify_peer);
  error_code ec;
  if (ca_file.empty()) context->set_default_verify_paths(ec);
  else context->load_verify_file(ca_file, ec);
  if (ec)
    throw std::runtime_error("cannot load the CA certificates" + (ca_file.empty() ? "" : " from " + ca_file) + ": " +
                             ec.message());
  return context;
}

// The cancel callback may outlive the exchange (the token keeps it): it reaches the exchange only while it lives.
struct HttpExchange::Hook {
  std::mutex mutex;
  HttpExchange* owner = nullptr;
};

HttpExchange::HttpExchange(const sdk::CancelToken& cancel, asio::ssl::context* tls)
    : tls_context_(tls), cancel_(cancel), hook_(std::make_shared<Hook>()) {
  hook_->owner = this;
  cancel_.on_cancel([hook = hook_] {
    std::lock_guard lock(hook->mutex);
    // The socket belongs to the calling thread's io_context: close it there (post wakes its epoll at once).
    if (hook->owner != nullptr) asio::post(hook->owner->io_, [owner = hook->owner] { owner->close(); });
  });
}

HttpExchange::~HttpExchange() {
  std::lock_guard lock(hook_->mutex);
  hook_->owner = nullptr;
}

void HttpExchange::close() noexcept {
  timer_.cancel();
  resolver_.cancel();
  if (plain_) plain_->close();
  if (tls_) beast::get_lowest_layer(*tls_).close();
}

// Runs one asynchronous step to completion on this thread; the stream's own expiry bounds it, a cancel closes it.
template <class Initiate> error_code HttpExchange::await(Initiate&& initiate) {
  error_code result = asio::error::operation_aborted;
  initiate([&result](error_code ec, auto&&...) { result = ec; });
  io_.restart();
  io_.run();
  return result;
}

bool HttpExchange::pause(milliseconds delay) {
  if (cancel_.cancelled()) return false;
  timer_.expires_after(delay);
  await([&](auto handler) { timer_.async_wait(std::move(handler)); });
  return !cancel_.cancelled();
}

ExchangeResult HttpExchange::run(const Endpoint& endpoint, http::verb method, const std::string& target, const std::string& body,
                                 const std::map<std::string, std::string>& headers, const ExchangeLimits& limits) {
  ExchangeResult r;
  const auto cancelled = [&r] {
    r.cancelled = true;
    r.error = "cancelled";
    return r;
  };
  if (cancel_.cancelled()) return cancelled();
  const auto remaining = [&] {
    return std::max(milliseconds(0), std::chrono::duration_cast<milliseconds>(limits.deadline - Clock::now()));
  };
  if (remaining() <= milliseconds(0)) {
    r.error = "deadline passed before the request";
    return r;
  }
  const std::string where = endpoint.host + ":" + endpoint.port;

  // Addresses: a literal needs no resolver (whose thread could not be interrupted); a name is bounded by `connect`.
  std::vector<tcp::endpoint> addresses;
  error_code ec;
  const unsigned short port = static_cast<unsigned short>(std::stoi(endpoint.port));
  if (const auto address = asio::ip::make_address(endpoint.host, ec); !ec) {
    addresses.emplace_back(address, port);
  } else {
    timer_.expires_after(std::min(limits.connect, remaining()));
    timer_.async_wait([this](error_code e) {
      if (!e) resolver_.cancel();
    });
    ec = await([&](auto handler) {
      resolver_.async_resolve(endpoint.host, endpoint.port,
                              [&, handler](error_code e, tcp::resolver::results_type found) mutable {
                                timer_.cancel();
                                for (const auto& entry : found) addresses.push_back(entry.endpoint());
                                handler(e);
                              });
    });
    if (cancel_.cancelled()) return cancelled();
    if (ec || addresses.empty()) {
      r.error = "cannot resolve " + endpoint.host + ": " + (ec ? ec.message() : "no address");
      r.retryable = ec != asio::error::host_not_found;
      return r;
    }
  }

  if (endpoint.tls) {
    tls_.emplace(io_, *tls_context_);
    SSL* ssl = tls_->native_handle();
    asio::ip::make_address(endpoint.host, ec);
    // The certificate must name the host we dialled: a name (with SNI), or an address literal.
    const bool named = static_cast<bool>(ec);
    if (named ? (SSL_set_tlsext_host_name(ssl, endpoint.host.c_str()) != 1 || SSL_set1_host(ssl, endpoint.host.c_str()) != 1)
              : X509_VERIFY_PARAM_set1_ip_asc(SSL_get0_param(ssl), endpoint.host.c_str()) != 1) {
      r.error = "cannot set up TLS host verification for " + endpoint.host;
      return r;
    }
    r = talk(*tls_, endpoint, method, target, body, headers, limits, addresses);
  } else {
    plain_.emplace(io_);
    r = talk(*plain_, endpoint, method, target, body, headers, limits, addresses);
  }
  close();
  if (cancel_.cancelled() && r.status == 0) return cancelled();
  if (!r.error.empty()) r.error += " (" + where + ")";
  return r;
}

template <class Stream>
ExchangeResult HttpExchange::talk(Stream& stream, const Endpoint& endpoint, http::verb method, const std::string& target,
                                  const std::string& body, const std::map<std::string, std::string>& headers,
                                  const ExchangeLimits& limits, const std::vector<tcp::endpoint>& addresses) {
  ExchangeResult r;
  auto& socket = beast::get_lowest_layer(stream);
  const auto remaining = [&] {
    return std::max(milliseconds(1), std::chrono::duration_cast<milliseconds>(limits.deadline - Clock::now()));
  };
  // The step's own bound, or the deadline when that comes first; the error names the one that ended it.
  const auto bound = [&](milliseconds step, const char* name, std::string& why) {
    const milliseconds left = remaining();
    why = step < left ? std::string(name) + " (" + ms_text(step) + ")" : std::string("the deadline");
    socket.expires_after(std::min(step, left));
  };
  std::string why;

  bound(limits.connect, "connect_timeout_ms", why);
  error_code ec = await([&](auto handler) { socket.async_connect(addresses, std::move(handler)); });
  if (ec) {
    r.error = ec == beast::error::timeout ? "connect timed out: " + why : "connect failed: " + ec.message();
    r.retryable = true;  // nothing was sent
    return r;
  }
  if constexpr (!std::is_same_v<Stream, beast::tcp_stream>) {
    bound(limits.connect, "connect_timeout_ms", why);
    ec = await([&](auto handler) { stream.async_handshake(asio::ssl::stream_base::client, std::move(handler)); });
    if (ec) {
      // A certificate that does not verify is a configuration or an attack: never retried, never skipped.
      r.error = ec == beast::error::timeout ? "TLS handshake timed out: " + why : "TLS handshake failed: " + ec.message();
      return r;
    }
  }

  http::request<http::string_body> request{method, endpoint.base_path + target, 11};
  const bool default_port = endpoint.port == (endpoint.tls ? "443" : "80");
  const bool v6 = endpoint.host.find(':') != std::string::npos;
  request.set(http::field::host, (v6 ? "[" + endpoint.host + "]" : endpoint.host) + (default_port ? "" : ":" + endpoint.port));
  request.set(http::field::user_agent, "rcand-chat/" BOOST_BEAST_VERSION_STRING);
  request.set(http::field::accept, "application/json");
  request.keep_alive(false);
  for (const auto& [name, value] : headers) request.set(name, value);
  if (!body.empty()) {
    request.set(http::field::content_type, "application/json");
    request.body() = body;
  }
  request.prepare_payload();
  bound(limits.first_byte, "first_byte_timeout_ms", why);
  ec = await([&](auto handler) { http::async_write(stream, request, std::move(handler)); });
  if (ec) {
    r.error =
        ec == beast::error::timeout ? "sending the request timed out: " + why : "sending the request failed: " + ec.message();
    return r;
  }

  beast::flat_buffer buffer;
  http::response_parser<http::string_body> parser;
  parser.header_limit(16 * 1024);
  parser.body_limit(limits.max_body);
  bound(limits.first_byte, "first_byte_timeout_ms", why);
  ec = await([&](auto handler) { http::async_read_header(stream, buffer, parser, std::move(handler)); });
  if (ec) {
    r.error = ec == beast::error::timeout ? "no answer within " + why : "reading the answer failed: " + ec.message();
    return r;
  }
  socket.expires_after(remaining());
  ec = await([&](auto handler) { http::async_read(stream, buffer, parser, std::move(handler)); });
  if (ec == http::error::body_limit) {
    r.error = "the answer exceeded " + std::to_string(limits.max_body) + " bytes (an endless stream?); cut off";
    return r;
  }
  if (ec) {
    r.error =
        ec == beast::error::timeout ? "the answer did not end before the deadline" : "reading the answer failed: " + ec.message();
    return r;
  }
  r.status = static_cast<int>(parser.get().result_int());
  r.body = std::move(parser.get().body());
  return r;
}

}  // namespace rcand::plugins::chat
