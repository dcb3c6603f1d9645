#include "libs/http/session.hpp"

#include <boost/asio/ssl/error.hpp>
#include <boost/asio/write.hpp>
#include <boost/beast/core/detect_ssl.hpp>
#include <boost/beast/core/string.hpp>
#include <boost/beast/http/error.hpp>
#include <boost/beast/http/read.hpp>
#include <boost/beast/http/write.hpp>

#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <exception>

#include <boost/beast/websocket/rfc6455.hpp>

#include "libs/http/request_builder.hpp"
#include "libs/http/responder.hpp"
#include "libs/http/tls_context.hpp"
#include "libs/http/upgrade.hpp"

namespace rcand::http::detail {

namespace net = boost::asio;
namespace beast = boost::beast;
namespace bhttp = boost::beast::http;

namespace {

constexpr std::size_t kReadChunk = 16 * 1024;
// After an error answer the rest of the request is read and dropped, so closing does not reset the connection
// before the client has read the answer; both bounds keep a hostile client from holding us there.
constexpr std::chrono::milliseconds kLingerTime{2000};
constexpr std::size_t kLingerBytes = 4 * 1024 * 1024;
constexpr std::string_view kContinue = "HTTP/1.1 100 Continue\r\n\r\n";
// The longest a busy-lane connection may take to send its request (a priority request comes with the connection).
constexpr std::chrono::milliseconds kBusyLaneWait{2000};

std::string format_endpoint(const net::ip::tcp::endpoint& endpoint) {
  const auto address = endpoint.address();
  std::string text = address.is_v6() ? "[" + address.to_string() + "]" : address.to_string();
  return text + ":" + std::to_string(endpoint.port());
}

std::string to_lower(std::string_view text) {
  std::string out{text};
  for (char& c : out) {
    if (c >= 'A' && c <= 'Z') c = static_cast<char>(c - 'A' + 'a');
  }
  return out;
}

bool is_token(std::string_view name) noexcept {
  if (name.empty()) return false;
  return std::all_of(name.begin(), name.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
           std::string_view{"!#$%&'*+-.^_`|~"}.find(c) != std::string_view::npos;
  });
}

// A header value must not end the header line early (response splitting).
bool is_safe_value(std::string_view value) noexcept {
  return value.find_first_of(std::string_view{"\r\n\0", 3}) == std::string_view::npos;
}

bool has_close_token(std::string_view value) { return to_lower(value).find("close") != std::string::npos; }

// Boost 1.74's Beast speaks boost::string_view.
beast::string_view bsv(std::string_view s) noexcept { return {s.data(), s.size()}; }

bool is_http_error(const beast::error_code& ec) {
  return &ec.category() == &bhttp::make_error_code(bhttp::error::bad_method).category();
}

ConnectionStream make_stream(Stream::socket_type socket, std::shared_ptr<net::ssl::context> tls) {
  if (tls) return ConnectionStream(Stream(std::move(socket)), std::move(tls));
  return ConnectionStream(Stream(std::move(socket)));
}

}  // namespace

Session::Session(ServerCore& core, IoSlot& slot, Stream::socket_type socket, std::unique_ptr<ConnectionTicket> ticket,
                 Placement placement, std::shared_ptr<net::ssl::context> tls)
    : core_(core),
      slot_(slot),
      ticket_(std::move(ticket)),
      placement_(placement),
      stream_(make_stream(std::move(socket), std::move(tls))) {}

void Session::start() {
  slot_.track(weak_from_this());
  if (core_.stopping.load(std::memory_order_acquire)) {
    close();
    return;
  }
  beast::error_code ec;
  auto endpoint = stream_.socket().remote_endpoint(ec);
  remote_ = ec ? std::string{"unknown"} : format_endpoint(endpoint);
  if (stream_.is_tls()) return handshake();
  if (placement_ != Placement::Worker) {
    // A client that sends its request with the connection (a stop does) is answered without another trip through
    // the loop: read what is there now, without waiting.
    auto& socket = stream_.socket();
    socket.non_blocking(true, ec);
    const std::size_t bytes = ec ? 0 : socket.read_some(buffer_.prepare(kReadChunk), ec);
    if (!ec) buffer_.commit(bytes);
  }
  wait_for_request();
}

PendingInput Session::pending_input(bool look_in_socket) noexcept {
  if (closed_) return PendingInput::Silent;
  if (answering_) return *answering_;
  try {
    if (parser_ && parser_->is_header_done()) {  // only its body is missing
      const auto& message = parser_->get();
      std::string start = std::string(message.method_string()) + ' ' + std::string(message.target()) + ' ';
      return classify_pending(start, core_.options.priority);
    }
    if (buffer_.size() > 0)  // the header is read whole before it is parsed, so this begins with its request line
      return classify_pending({static_cast<const char*>(buffer_.data().data()), buffer_.size()}, core_.options.priority);
    if (!look_in_socket) return PendingInput::Silent;
    char peeked[256];
    const ssize_t got = ::recv(stream_.socket().native_handle(), peeked, sizeof peeked, MSG_PEEK | MSG_DONTWAIT);
    return classify_pending({peeked, got > 0 ? static_cast<std::size_t>(got) : 0}, core_.options.priority);
  } catch (...) {  // allocation failure: keep the waiter
    return PendingInput::Priority;
  }
}

void Session::close() noexcept {
  if (closed_) return;
  closed_ = true;
  // The producer of a streamed answer sees closed() and stops pushing.
  if (body_stream_) body_stream_->close();
  if (offer_timer_) offer_timer_->cancel();
  stream_.close();  // also cancels the stream's timers, so every pending operation completes
}

void Session::handshake() {
  fresh_ = false;  // the first request gets its own header_timeout once the handshake is done
  stream_.expires_after(core_.options.header_timeout);
  // A TLS client speaks first with a handshake record; anything else (plain HTTP) is answered in plain words.
  beast::async_detect_ssl(stream_.next_layer(), buffer_, [self = shared_from_this()](beast::error_code ec, bool is_tls) {
    if (ec || self->closed_) {
      if (!self->closed_) self->core_.log->debug("{}: closed before its TLS handshake: {}", self->remote_, ec.message());
      return self->close();
    }
    if (!is_tls) return self->refuse_plain_http();
    self->stream_.tls()->async_handshake(
        net::ssl::stream_base::server, self->buffer_.data(), [self](beast::error_code handshake_ec, std::size_t used) {
          if (self->closed_) return;
          if (handshake_ec) {
            self->core_.log->debug("{}: TLS handshake failed: {}", self->remote_,
                                   tls_failure(self->stream_.tls()->native_handle(), handshake_ec));
            return self->close();
          }
          self->buffer_.consume(used);
          self->stream_.expires_after(self->core_.options.header_timeout);
          self->fresh_ = true;
          self->wait_for_request();
        });
  });
}

void Session::refuse_plain_http() {
  raw_ = true;
  core_.log->debug("{}: plain HTTP on the TLS port; answering 400 TLS_REQUIRED", remote_);
  auto response =
      error_response(400, "TLS_REQUIRED", "this port speaks HTTPS only: use https:// (plain HTTP is served on 127.0.0.1 only)");
  bhttp::response<bhttp::string_body> message{bhttp::status::bad_request, 11};
  message.set(bhttp::field::server, "rcand");
  message.set(bhttp::field::content_type, bsv(response.content_type));
  message.keep_alive(false);
  message.body() = std::move(response.body);
  message.prepare_payload();
  response_ = std::move(message);
  stream_.expires_after(core_.options.idle_timeout);
  bhttp::async_write(stream_.next_layer(), response_,
                     [self = shared_from_this()](beast::error_code ec, std::size_t) { self->on_write(ec, true); });
}

void Session::wait_for_request() {
  if (closed_) return;
  if (fresh_ || buffer_.size() > 0) {  // first request, or the next one is already (partly) buffered
    fresh_ = false;
    stream_.expires_after(placement_ == Placement::BusyLane ? std::min(core_.options.header_timeout, kBusyLaneWait)
                                                            : core_.options.header_timeout);
    if (buffer_.size() > 0) return parse_buffered();
    read_header();
    return;
  }
  // Idle between requests: wait for the first byte under idle_timeout; the request itself then gets header_timeout.
  stream_.expires_after(core_.options.idle_timeout);
  stream_.async_read_some(buffer_.prepare(kReadChunk), [self = shared_from_this()](beast::error_code ec, std::size_t bytes) {
    if (ec) return self->on_read_error(ec);
    self->buffer_.commit(bytes);
    if (self->closed_) return;
    self->stream_.expires_after(self->core_.options.header_timeout);
    self->parse_buffered();
  });
}

void Session::new_parser() {
  parser_.emplace();
  configure_parser(*parser_, core_.options.body_limit);
}

void Session::parse_buffered() {
  // Fast path: a small request usually arrives whole in one read. Parsing it here skips Beast's read operation
  // (and the extra trip through the loop it makes when no I/O is needed); anything incomplete falls back to it.
  new_parser();
  beast::error_code ec;
  buffer_.consume(parser_->put(buffer_.data(), ec));
  if (ec && ec != bhttp::error::need_more) return on_read_error(ec);
  if (parser_->is_done()) return dispatch_request();
  if (parser_->is_header_done()) return on_header({});
  bhttp::async_read_header(stream_, buffer_, *parser_,
                           [self = shared_from_this()](beast::error_code read_ec, std::size_t) { self->on_header(read_ec); });
}

void Session::read_header() {
  new_parser();
  // The deadline set before this covers header and body: a slow-loris client is cut off at header_timeout.
  bhttp::async_read_header(stream_, buffer_, *parser_,
                           [self = shared_from_this()](beast::error_code ec, std::size_t) { self->on_header(ec); });
}

void Session::on_header(beast::error_code ec) {
  if (ec) return on_read_error(ec);
  if (closed_) return;
  if (parser_->is_done()) return dispatch_request();
  if (auto refusal = check_header(parser_->get())) {  // before reading a body that would be refused anyway
    core_.log->debug("{}: {}", remote_, refusal->message);
    return send_error_and_close(refusal->status, refusal->code, refusal->message);
  }
  const auto& header = parser_->get();
  if (header.version() >= 11 && beast::iequals(header[bhttp::field::expect], "100-continue")) {
    net::async_write(stream_, net::buffer(kContinue.data(), kContinue.size()),
                     [self = shared_from_this()](beast::error_code write_ec, std::size_t) {
                       if (write_ec) return self->close();
                       self->read_body();
                     });
    return;
  }
  read_body();
}

void Session::read_body() {
  if (closed_) return;
  bhttp::async_read(stream_, buffer_, *parser_, [self = shared_from_this()](beast::error_code ec, std::size_t) {
    if (ec) return self->on_read_error(ec);
    if (self->closed_) return;
    self->dispatch_request();
  });
}

void Session::on_read_error(beast::error_code ec) {
  if (closed_) return;  // stop() closed us
  if (ec == bhttp::error::end_of_stream || ec == net::error::eof) return close();
  if (ec == beast::error::timeout) {
    core_.log->debug("{}: request or idle timeout, closing", remote_);
    return close();
  }
  if (ec == bhttp::error::body_limit) {
    core_.log->debug("{}: request body over the limit of {} bytes", remote_, core_.options.body_limit);
    return send_error_and_close(413, "PAYLOAD_TOO_LARGE",
                                "request body exceeds the limit of " + std::to_string(core_.options.body_limit) + " bytes");
  }
  if (ec == bhttp::error::header_limit) {
    core_.log->debug("{}: request header over {} bytes", remote_, kHeaderLimit);
    return send_error_and_close(431, "BAD_REQUEST",
                                "request header exceeds the limit of " + std::to_string(kHeaderLimit) + " bytes");
  }
  if (is_http_error(ec) && ec != bhttp::error::partial_message) {
    core_.log->debug("{}: malformed request: {}", remote_, ec.message());
    return send_error_and_close(400, "BAD_REQUEST", "malformed HTTP request: " + ec.message());
  }
  core_.log->debug("{}: read failed: {}", remote_, ec.message());
  close();
}

void Session::dispatch_request() {
  message_ = parser_->release();  // the parser is done with it; a new one reads the next request
  auto& message = message_;
  version_ = message.version();
  keep_alive_ = message.keep_alive();
  head_ = message.method() == bhttp::verb::head;

  if (auto refusal = check_header(message)) {
    core_.log->debug("{}: {}", remote_, refusal->message);
    return send_error_and_close(refusal->status, refusal->code, refusal->message);
  }
  Request request;
  if (auto problem = build_request(message, remote_, request); !problem.empty()) {
    core_.log->debug("{}: {}", remote_, problem);
    return send_error_and_close(400, "BAD_REQUEST", problem);
  }
  request.secure = stream_.is_tls();
  const bool priority = core_.is_priority(request);
  if (placement_ == Placement::BusyLane) answering_ = priority ? PendingInput::Priority : PendingInput::Ordinary;
  if (placement_ != Placement::Worker && !priority) {
    if (placement_ == Placement::BusyLane) return answer_busy();
    return move_to_worker(std::move(request));
  }
  if (placement_ == Placement::BusyLane) keep_alive_ = false;  // beyond the limits: one answer, then the slot is freed
  handle(std::move(request));
}

void Session::handle(Request request) {
  // Never the target or query: a ?token= may ride there.
  core_.log->trace("{}: {} {}", remote_, request.method, request.path);
  if (refused_by_screen(request)) return;
  if (core_.options.upgrade && beast::websocket::is_upgrade(message_) && try_upgrade(request)) return;

  awaiting_response_ = true;
  auto responder = std::make_shared<Responder>(shared_from_this());
  const std::string method = request.method;
  const std::string path = request.path;
  try {
    core_.handler(std::move(request), [responder](Response response) { responder->respond(std::move(response)); });
  } catch (const std::exception& e) {
    core_.log->error("{}: handler for {} {} threw: {}", remote_, method, path, e.what());
    responder->respond(error_response(500, "INTERNAL", "internal error"));
  } catch (...) {
    core_.log->error("{}: handler for {} {} threw a non-standard exception", remote_, method, path);
    responder->respond(error_response(500, "INTERNAL", "internal error"));
  }
}

void Session::answer_busy() {
  keep_alive_ = false;
  auto response = error_response(503, "SERVER_BUSY",
                                 "the server is at its connection limit (" + std::to_string(core_.options.max_connections) +
                                     " in all, " + std::to_string(core_.options.max_connections_per_address) +
                                     " per client address); only the e-stop is served beyond it. Retry later");
  response.headers.emplace_back("Retry-After", "1");
  write(std::move(response), true);
}

void Session::move_to_worker(Request request) {
  // A socket belongs to one loop: the descriptor is duplicated onto a socket of the worker's loop and this one is
  // closed, which leaves the connection itself untouched. Nothing of this session is pending at this point.
  IoSlot& worker = core_.next_worker();
  beast::error_code ec;
  auto& socket = stream_.socket();
  const auto protocol = socket.local_endpoint(ec).protocol();
  const int fd = ec ? -1 : ::dup(socket.native_handle());
  close();
  if (fd < 0) {
    core_.log->warn("{}: cannot hand the connection to a worker ({}); closing it", remote_,
                    ec ? ec.message() : std::string(std::strerror(errno)));
    return;
  }
  try {
    Stream::socket_type moved(worker.ioc);
    moved.assign(protocol, fd, ec);
    if (ec) {
      ::close(fd);
      core_.log->warn("{}: cannot hand the connection to a worker ({}); closing it", remote_, ec.message());
      return;
    }
    auto next = std::make_shared<Session>(core_, worker, std::move(moved), std::move(ticket_), Placement::Worker);
    next->remote_ = remote_;
    next->buffer_ = std::move(buffer_);
    next->message_ = std::move(message_);
    next->version_ = version_;
    next->keep_alive_ = keep_alive_;
    next->head_ = head_;
    next->fresh_ = false;
    net::post(worker.ioc, [next = std::move(next), request = std::move(request)]() mutable {
      next->slot_.track(next->weak_from_this());
      if (next->core_.stopping.load(std::memory_order_acquire)) return next->close();
      next->handle(std::move(request));
    });
  } catch (const std::exception& e) {
    core_.log->error("{}: cannot hand the connection to a worker: {}", remote_, e.what());
  }
}

bool Session::refused_by_screen(const Request& request) {
  if (!core_.options.screen) return false;
  std::optional<Response> refusal;
  try {
    refusal = core_.options.screen(request);
  } catch (const std::exception& e) {
    core_.log->error("{}: screen for {} threw: {}", remote_, request.path, e.what());
    refusal = error_response(500, "INTERNAL", "internal error");
  }
  if (!refusal) return false;
  keep_alive_ = false;  // an upgrade too: the refusal is plain HTTP, then the connection closes
  write(std::move(*refusal), true);
  return true;
}

bool Session::try_upgrade(Request& request) {
  UpgradeVerdict verdict;
  try {
    verdict = core_.options.upgrade(request);
  } catch (const std::exception& e) {
    core_.log->error("{}: upgrade hook for {} threw: {}", remote_, request.path, e.what());
    verdict.refuse = error_response(500, "INTERNAL", "internal error");
  }
  // RFC 6455 §4.4: a version we do not speak gets 426 naming the one we do (as JSON, like every error here).
  if (auto version = request.header("sec-websocket-version"); verdict.take && (!version || *version != "13")) {
    verdict.take = nullptr;
    verdict.refuse =
        error_response(426, "UPGRADE_REQUIRED", "unsupported WebSocket version (Sec-WebSocket-Version): only 13 is spoken");
    verdict.refuse->headers.emplace_back("Sec-WebSocket-Version", "13");
  }
  if (verdict.take) {
    closed_ = true;  // the stream is the taker's from here on; this session just ends
    Upgraded upgraded{std::move(stream_), std::move(message_), std::move(buffer_), std::move(request)};
    try {
      verdict.take(std::move(upgraded));
    } catch (const std::exception& e) {
      core_.log->error("{}: taking the upgraded connection failed: {}", remote_, e.what());
    }
    return true;
  }
  if (verdict.refuse) {
    keep_alive_ = false;
    write(std::move(*verdict.refuse), true);
    return true;
  }
  return false;
}

void Session::send(Response response) {
  if (closed_ || !awaiting_response_) {
    if (response.stream) response.stream->close();  // nobody will ever take its parts
    return;
  }
  awaiting_response_ = false;
  write(std::move(response), !keep_alive_ || core_.stopping.load(std::memory_order_relaxed));
}

void Session::send_error_and_close(int status, std::string_view code, std::string_view message) {
  keep_alive_ = false;
  head_ = false;
  version_ = parser_ && parser_->is_header_done() ? parser_->get().version() : 11;
  write(error_response(status, code, message), true);
}

void Session::write(Response response, bool close_after) {
  if (response.status < 200 || response.status > 599) {
    core_.log->error("{}: handler answered with invalid status {}; sending 500", remote_, response.status);
    if (response.stream) response.stream->close();
    response = error_response(500, "INTERNAL", "internal error");
  }
  bhttp::response<bhttp::string_body> message;
  message.version(version_);
  message.result(static_cast<unsigned>(response.status));
  message.set(bhttp::field::server, "rcand");
  if (!response.content_type.empty() && is_safe_value(response.content_type)) {
    message.set(bhttp::field::content_type, bsv(response.content_type));
  }
  for (auto& [name, value] : response.headers) {
    if (!is_token(name) || !is_safe_value(value)) {
      core_.log->warn("{}: dropping an invalid response header", remote_);  // neither name nor value: may be secret
      continue;
    }
    if (beast::iequals(bsv(name), "connection")) {
      if (has_close_token(value)) close_after = true;
      continue;
    }
    if (beast::iequals(bsv(name), "content-length") || beast::iequals(bsv(name), "transfer-encoding") ||
        beast::iequals(bsv(name), "server")) {
      continue;
    }
    message.insert(bsv(name), bsv(value));
  }
  if (response.stream) {  // its end is the connection's: no Content-Length, no keep-alive
    body_stream_ = std::move(response.stream);
    close_after = true;
    if (head_) body_stream_->close();
  }
  message.keep_alive(!close_after);
  // 204 and 304 carry neither a body nor Content-Length (RFC 9110 §8.6); HEAD gets the length without the body.
  if (!body_stream_ && response.status != 204 && response.status != 304) {
    message.content_length(response.body.size());
    if (!head_) message.body() = std::move(response.body);
  }
  response_ = std::move(message);

  stream_.expires_after(core_.options.idle_timeout);
  bhttp::async_write(stream_, response_, [self = shared_from_this(), close_after](beast::error_code ec, std::size_t) {
    self->on_write(ec, close_after);
  });
}

void Session::on_write(beast::error_code ec, bool close_after) {
  if (ec) {
    if (!closed_) core_.log->debug("{}: write failed: {}", remote_, ec.message());
    return close();
  }
  if (closed_) return;
  if (body_stream_ && !streaming_) return start_streaming();
  if (close_after) return linger_close();
  // On the accept loop a connection stays while it sends only priority requests (a stop button's kept-alive
  // connection); its first other request moves it to a worker (dispatch_request).
  wait_for_request();
}

void Session::linger_close() {
  if (stream_.is_tls() && !raw_) {
    // close_notify, then the client's (or its end): bounded like the plain linger below.
    stream_.expires_after(std::min(core_.options.header_timeout, kLingerTime));
    stream_.tls()->async_shutdown([self = shared_from_this()](beast::error_code) { self->close(); });
    return;
  }
  beast::error_code ec;
  stream_.socket().shutdown(net::ip::tcp::socket::shutdown_send, ec);
  if (ec) return close();
  stream_.expires_after(std::min(core_.options.header_timeout, kLingerTime));
  buffer_.consume(buffer_.size());
  drain();
}

void Session::drain() {
  stream_.next_layer().async_read_some(buffer_.prepare(kReadChunk),
                                       [self = shared_from_this()](beast::error_code ec, std::size_t bytes) {
                                         self->drained_ += bytes;
                                         if (ec || self->closed_ || self->drained_ > kLingerBytes) return self->close();
                                         self->drain();
                                       });
}

}  // namespace rcand::http::detail

namespace rcand::http::detail {

void Session::start_streaming() {
  streaming_ = true;
  offer_timer_.emplace(slot_.ioc);
  body_stream_->attach([weak = weak_from_this(), executor = executor()] {
    net::post(executor, [weak] {
      if (auto self = weak.lock()) self->pump();
    });
  });
  stream_.expires_never();  // the watching read has no deadline; each part's write gets stream_stall_timeout
  watch_client();
  pump();
}

void Session::pump() {
  if (closed_ || writing_part_ || ending_) return;
  switch (body_stream_->next(part_)) {
    case ResponseStream::Next::Wait: return await_part();  // push() wakes us
    case ResponseStream::Next::End: return end_stream();
    case ResponseStream::Next::Part: break;
  }
  ++offer_waits_;  // a part came: the wait for one is over
  offer_timer_->cancel();
  writing_part_ = true;
  const std::array<net::const_buffer, 3> buffers{
      net::buffer(part_.head), part_.data ? net::buffer(*part_.data) : net::const_buffer(), net::buffer(part_.tail)};
  stream_.expires_after(core_.options.stream_stall_timeout);  // the read is pending: this times the write only
  net::async_write(stream_, buffers, [self = shared_from_this()](beast::error_code ec, std::size_t) {
    self->writing_part_ = false;
    if (ec) {
      if (!self->closed_) self->core_.log->debug("{}: stream write failed: {}", self->remote_, ec.message());
      return self->close();
    }
    self->body_stream_->written(self->part_.data ? self->part_.data->size() : 0);
    self->part_ = {};  // the frame is shared: let it go as soon as it is written
    self->pump();
  });
}

void Session::await_part() {
  // A stream offered no part for stream_stall_timeout ends like one whose client does not read: a viewer that asks for
  // (almost) no frames, or a producer that stalled, holds its connection and its slot for that long at most.
  offer_timer_->expires_after(core_.options.stream_stall_timeout);
  offer_timer_->async_wait([self = shared_from_this(), armed = ++offer_waits_](beast::error_code ec) {
    if (ec || self->closed_ || self->ending_ || armed != self->offer_waits_) return;
    self->core_.log->debug("{}: stream offered no part for {} ms; ended", self->remote_,
                           self->core_.options.stream_stall_timeout.count());
    self->body_stream_->close();  // its producer lets go at once (and whatever the stream held: a slot)
    self->end_stream();           // then a clean end: FIN after the last whole part
  });
}

void Session::watch_client() {
  // Whatever the client sends while it watches is read and dropped; its end (or an error) ends the stream.
  stream_.async_read_some(buffer_.prepare(kReadChunk), [self = shared_from_this()](beast::error_code ec, std::size_t) {
    if (self->closed_) return;
    if (self->ending_) return self->linger_close();
    if (ec) return self->close();
    self->watch_client();
  });
}

void Session::end_stream() {
  ending_ = true;
  beast::error_code ec;
  stream_.socket().cancel(ec);  // completes the watching read, which then closes gracefully (linger_close)
  if (ec) close();
}

}  // namespace rcand::http::detail
