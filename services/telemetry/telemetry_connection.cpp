#include "services/telemetry/telemetry_connection.hpp"

#include <linux/sockios.h>
#include <sys/ioctl.h>

#include <boost/asio/post.hpp>
#include <boost/beast/core/buffers_to_string.hpp>
#include <boost/beast/websocket.hpp>

#include "libs/base/bounded_text.hpp"
#include "libs/base/json_body.hpp"
#include "libs/base/logging.hpp"
#include "services/telemetry/telemetry_hub.hpp"

namespace rcand::services::telemetry {

namespace net = boost::asio;
namespace beast = boost::beast;
namespace websocket = boost::beast::websocket;
using nlohmann::json;

namespace {
// Answers queued for a client that sends faster than it reads: past this it is dropped like a slow reader.
constexpr std::size_t kMaxAnswers = 8;
// Where a stop came from when the client does not say (GET /api/estop's "from"; docs/protocol.md §6.7).
constexpr std::string_view kDefaultStopFrom = "a telemetry client (WebSocket)";
}  // namespace

Connection::Connection(std::weak_ptr<TelemetryHub> hub, http::UpgradeStream stream, std::string remote, Credential credential,
                       std::shared_ptr<void> slot)
    : hub_(std::move(hub)),
      ws_(std::move(stream)),
      remote_(std::move(remote)),
      credential_(std::move(credential)),
      slot_(std::move(slot)) {}

void Connection::accept(beast::http::request<beast::http::string_body> raw) {
  auto hub = hub_.lock();
  if (!hub) return;
  beast::get_lowest_layer(ws_).expires_never();  // the websocket's own timeouts from here
  // Pings after 15 s without a word from the client, closed after 30: a vanished client is noticed even when idle.
  ws_.set_option(websocket::stream_base::timeout{std::chrono::seconds(5), std::chrono::seconds(30), true});
  ws_.set_option(websocket::stream_base::decorator(
      [](websocket::response_type& response) { response.set(beast::http::field::server, "rcand"); }));
  ws_.read_message_max(hub->options().max_message_bytes);
  ws_.async_accept(raw, [self = shared_from_this()](beast::error_code ec) {
    if (ec) return self->shut(std::nullopt);
    self->open_ = true;
    self->read();
    self->write_next();
  });
}

void Connection::offer(Bytes frame) {
  net::post(ws_.get_executor(),
            [self = shared_from_this(), frame = std::move(frame)]() mutable { self->take_frame(std::move(frame)); });
}

void Connection::close() {
  net::post(ws_.get_executor(), [self = shared_from_this()] {
    self->shut(websocket::close_reason(websocket::close_code::going_away, "rcand is stopping"));
  });
}

void Connection::take_frame(Bytes frame) {
  if (closed_ || !credential_holds()) return;
  auto hub = hub_.lock();
  if (!hub) return;
  if (behind(frame->size())) {
    hub->stats().dropped_slow.fetch_add(1);
    logger("telemetry")->info("telemetry: {} ({}) is not keeping up; dropped", remote_, bounded_text(credential_.principal, 64));
    return shut(std::nullopt);  // no close frame: it would only queue behind what the client does not read
  }
  if (pending_) hub->stats().frames_replaced.fetch_add(1);
  pending_ = std::move(frame);
  write_next();
}

// The client's socket still holds undelivered bytes worth several frames (SIOCOUTQ: unsent plus unacknowledged),
// or one write has been waiting for the socket for too long.
bool Connection::behind(std::size_t frame_bytes) {
  auto hub = hub_.lock();
  if (!hub || !open_) return false;
  const HubOptions& o = hub->options();
  int queued = 0;
  auto& socket = beast::get_lowest_layer(ws_).socket();
  if (::ioctl(socket.native_handle(), SIOCOUTQ, &queued) == 0 &&
      static_cast<std::size_t>(queued) > std::max(o.min_backlog_bytes, o.backlog_frames * frame_bytes))
    return true;
  return writing_ && std::chrono::steady_clock::now() - write_started_ > o.write_stall;
}

void Connection::write_next() {
  if (closed_ || writing_ || !open_) return;
  Bytes next;
  const bool frame = answers_.empty();
  if (!frame) {
    next = std::move(answers_.front());
    answers_.pop_front();
  } else if (pending_) {
    next = std::move(pending_);
    pending_.reset();
  } else {
    return;
  }
  writing_ = true;
  write_started_ = std::chrono::steady_clock::now();
  ws_.text(true);
  ws_.async_write(net::buffer(*next), [self = shared_from_this(), next, frame](beast::error_code ec, std::size_t) {
    self->writing_ = false;
    if (ec) return self->shut(std::nullopt);
    if (frame)
      if (auto hub = self->hub_.lock()) hub->stats().frames_sent.fetch_add(1, std::memory_order_relaxed);
    self->write_next();
  });
}

void Connection::read() {
  ws_.async_read(buffer_, [self = shared_from_this()](beast::error_code ec, std::size_t) {
    if (ec) return self->shut(std::nullopt);  // closed, timed out, or over max_message_bytes (Beast sent 1009)
    std::string text = beast::buffers_to_string(self->buffer_.data());
    self->buffer_.consume(self->buffer_.size());
    self->on_message(text, !self->ws_.got_text());
    if (!self->closed_) self->read();
  });
}

void Connection::on_message(const std::string& text, bool binary) {
  if (closed_ || !credential_holds()) return;
  const JsonBody body = binary ? JsonBody{nullptr, "binary"} : parse_json_body(text);
  if (!body.error.empty() || !body.value.is_object())
    return error("BAD_REQUEST", R"(a message is a JSON object (text), such as {"cmd":"stop"})");
  const auto cmd = body.value.find("cmd");
  if (cmd == body.value.end() || !cmd->is_string()) return error("BAD_REQUEST", R"("cmd" must be a string, such as "stop")");
  if (*cmd != "stop")
    return error("UNKNOWN_COMMAND", "unknown cmd '" + bounded_text(cmd->get<std::string>(), 64) + R"('; the only one is "stop")");
  json stop = json::object();  // POST /api/stop's body: the client's "reason" and "from", when they are strings
  for (const char* key : {"reason", "from"})
    if (const auto it = body.value.find(key); it != body.value.end() && it->is_string())
      stop[key] = bounded_text(it->get<std::string>());
  if (!stop.contains("from")) stop["from"] = kDefaultStopFrom;
  request_stop(std::move(stop));
}

// POST /api/stop's row, through the Api, with this client's credential and address: the scope check (status), the
// audit entry and the latch are exactly an HTTP stop's. The stop handler runs inline, here, now.
void Connection::request_stop(json body) {
  auto hub = hub_.lock();
  if (!hub) return;
  http::Request request;
  request.method = "POST";
  request.target = request.path = "/api/stop";
  request.remote = remote_;
  if (!credential_.bearer.empty()) request.headers["authorization"] = "Bearer " + credential_.bearer;
  request.body = body.dump(-1, ' ', false, json::error_handler_t::replace);
  hub->stats().stops.fetch_add(1);
  hub->api().handle(std::move(request), [weak = weak_from_this()](http::Response response) {
    auto self = weak.lock();
    if (!self) return;
    net::post(self->ws_.get_executor(), [self, response = std::move(response)] {
      json body = json::parse(response.body, nullptr, false);
      if (!body.is_object()) body = json::object();
      if (response.status == 200) {
        body["type"] = "stopped";
        return self->answer(body);
      }
      self->error(body.value("code", std::string("STOP_FAILED")), body.value("error", std::string("the stop was refused")));
    });
  });
}

void Connection::error(std::string_view code, const std::string& message) {
  if (auto hub = hub_.lock()) hub->stats().bad_messages.fetch_add(1);
  answer({{"type", "error"}, {"code", code}, {"error", message}});
}

void Connection::answer(const json& message) {
  if (closed_) return;
  if (answers_.size() >= kMaxAnswers) {  // it sends and does not read
    if (auto hub = hub_.lock()) hub->stats().dropped_slow.fetch_add(1);
    return shut(std::nullopt);
  }
  answers_.push_back(std::make_shared<const std::string>(message.dump(-1, ' ', false, json::error_handler_t::replace)));
  write_next();
}

bool Connection::credential_holds() {
  if (closed_) return false;
  auto hub = hub_.lock();
  if (!hub) return false;
  const std::int64_t now_s =
      std::chrono::duration_cast<std::chrono::seconds>(std::chrono::system_clock::now().time_since_epoch()).count();
  const char* why = nullptr;
  if (credential_.expires_s && now_s > *credential_.expires_s) {
    why = "telemetry credential expired (JWT exp); reconnect with a fresh one";
  } else if (const auto generation = hub->auth().generation(); generation != credential_.generation) {
    credential_.generation = generation;  // read first: a reload racing this check is caught by the next one
    std::optional<std::string_view> bearer;
    if (!credential_.bearer.empty()) bearer = credential_.bearer;
    auto verdict = hub->auth().authorize(bearer, sdk::Scope::Status, now_s);
    if (auto* principal = std::get_if<kernel::Principal>(&verdict)) credential_.expires_s = principal->expires_s;
    else why = "telemetry credential revoked (config reload)";
  }
  if (why == nullptr) return true;
  hub->stats().closed_credential.fetch_add(1);
  logger("telemetry")->info("telemetry: {} ({}) closed: {}", remote_, bounded_text(credential_.principal, 64), why);
  shut(websocket::close_reason(websocket::close_code::policy_error, why));
  return false;
}

void Connection::shut(std::optional<websocket::close_reason> reason) {
  if (closed_) return;
  closed_ = true;
  pending_.reset();
  answers_.clear();
  auto& lowest = beast::get_lowest_layer(ws_);
  if (reason && open_ && !writing_ && ws_.is_open()) {
    // A close frame when the client can take one; the socket goes when it completes or after 500 ms.
    lowest.expires_after(std::chrono::milliseconds(500));
    ws_.async_close(*reason, [self = shared_from_this()](beast::error_code) { beast::get_lowest_layer(self->ws_).close(); });
  } else {
    lowest.close();
  }
  if (auto hub = hub_.lock()) hub->closed(shared_from_this());
}

}  // namespace rcand::services::telemetry
