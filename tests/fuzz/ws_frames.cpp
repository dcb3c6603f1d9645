// libFuzzer target: what WebSocket clients send rcand - WS /ws/telemetry and WS /ws/r2r - through the simulated
// robot's real HTTP server (serve_robot()), over two long-lived connections authenticated as the owner. The first
// byte picks the socket (bit 0), a text or binary message (bit 1) and how it is cut into frames (bits 2..4: one
// frame, or fragments of 1, 2, 3, 7, 16, 64 or 512 bytes); the rest is the message.
// Invariants:
//  - telemetry: every message gets exactly one answer, {"type":"stopped",...} for {"cmd":"stop"} (the owner may
//    stop) and {"type":"error","code","error"} otherwise; frames in between are {"type":"telemetry"};
//  - R2R: everything the robot sends back is an R2R message that parses (parse_envelope) from this robot, and an
//    error reply carries a code 100..105; a marker command sent after each input is answered (the connection still
//    works, and the input was handled first);
//  - a connection closes only for a message over its limit (telemetry 4 KiB, R2R 64 KiB) or a text message that
//    is not UTF-8 (RFC 6455 1009 and 1007); it is then opened again.
// Between inputs the e-stop is cleared and nav cancelled (sim_robot.hpp), as an R2R command or a stop may move or
// latch the robot.
#include <boost/asio/buffer.hpp>
#include <boost/asio/ip/tcp.hpp>
#include <boost/beast/websocket.hpp>

#include <algorithm>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

#include "fuzz_check.hpp"
#include "libs/base/json_body.hpp"
#include "libs/r2r_wire/envelope.hpp"
#include "sim_robot.hpp"
#include "ws_client.hpp"

namespace {

using nlohmann::json;
using namespace std::chrono_literals;
namespace beast = boost::beast;

constexpr std::size_t kTelemetryMaxMessage = 4096;                  // services/telemetry/telemetry_hub.hpp
constexpr std::size_t kR2rMaxMessage = 64 * 1024;                   // services/r2r/transports/websocket_transport.hpp
constexpr std::size_t kFragments[] = {0, 1, 2, 3, 7, 16, 64, 512};  // 0: the message in one frame
constexpr auto kAnswerWithin = 10s;

// RFC 3629 UTF-8 (no overlongs, no surrogates, nothing above U+10FFFF): what RFC 6455 requires of a text message.
bool valid_utf8(std::string_view text) {
  std::size_t i = 0;
  while (i < text.size()) {
    const auto c = static_cast<unsigned char>(text[i]);
    std::size_t n = 0;
    unsigned long cp = 0;
    if (c < 0x80) {
      ++i;
      continue;
    } else if (c >= 0xC2 && c <= 0xDF) {
      n = 1, cp = c & 0x1F;
    } else if (c >= 0xE0 && c <= 0xEF) {
      n = 2, cp = c & 0x0F;
    } else if (c >= 0xF0 && c <= 0xF4) {
      n = 3, cp = c & 0x07;
    } else {
      return false;
    }
    if (i + n >= text.size()) return false;
    for (std::size_t k = 1; k <= n; ++k) {
      const auto cc = static_cast<unsigned char>(text[i + k]);
      if ((cc & 0xC0) != 0x80) return false;
      cp = cp << 6 | (cc & 0x3F);
    }
    if ((n == 2 && (cp < 0x800 || (cp >= 0xD800 && cp <= 0xDFFF))) || (n == 3 && (cp < 0x10000 || cp > 0x10FFFF))) return false;
    i += n + 1;
  }
  return true;
}

class Socket {
 public:
  explicit Socket(const char* path) : path_(path) {}

  // Sends one message cut into frames of `fragment` bytes (0: one frame). False when the connection is gone.
  bool send(const std::string& message, bool binary, std::size_t fragment) {
    auto& c = client();
    c.ws.binary(binary);
    beast::error_code result = boost::asio::error::would_block;
    if (fragment == 0 || message.size() <= fragment) {
      c.ws.async_write(boost::asio::buffer(message), [&](beast::error_code ec, std::size_t) { result = ec; });
      run(c);
    } else {
      result = {};
      for (std::size_t at = 0; at < message.size() && !result.failed(); at += fragment) {
        const bool last = at + fragment >= message.size();
        result = boost::asio::error::would_block;
        c.ws.async_write_some(last, boost::asio::buffer(message.data() + at, std::min(fragment, message.size() - at)),
                              [&](beast::error_code ec, std::size_t) { result = ec; });
        run(c);
        if (result == boost::asio::error::would_block) break;
      }
    }
    RCAND_FUZZ_CHECK(result != boost::asio::error::would_block, "a write to the robot did not finish within 10 s");
    if (result) drop();
    return !result;
  }

  // The next message, or nullopt when the connection closed (then it is dropped, to be opened again).
  std::optional<std::string> read() {
    beast::error_code error;
    auto text = client().read(kAnswerWithin, &error);
    RCAND_FUZZ_CHECK(error != boost::asio::error::would_block, "the robot did not answer within 10 s");
    if (!text) drop();
    return text;
  }

  void drop() { client_.reset(); }

 private:
  rcand::test::WsClient& client() {
    if (!client_) {
      client_ = std::make_unique<rcand::test::WsClient>();
      const int status = client_->connect(rcand::fuzz::serve_robot(), rcand::fuzz::kOwnerToken, path_);
      RCAND_FUZZ_CHECK(status == 101, "the owner's upgrade is accepted");
      // Each input is a message and a probe (or several fragments) back to back: without this, Nagle holds the
      // second write for the server's delayed ACK, 40 ms an input.
      beast::get_lowest_layer(client_->ws).socket().set_option(boost::asio::ip::tcp::no_delay(true));
    }
    return *client_;
  }
  static void run(rcand::test::WsClient& c) {
    c.ioc.run_for(kAnswerWithin);
    c.ioc.restart();
  }

  const char* path_;
  std::unique_ptr<rcand::test::WsClient> client_;
};

Socket& telemetry() {
  static Socket* socket = new Socket("/ws/telemetry");
  return *socket;
}
Socket& r2r() {
  static Socket* socket = new Socket("/ws/r2r");
  return *socket;
}

// A close is explained by a message over the limit or a text message that is not UTF-8.
bool may_close(const std::string& message, bool binary, std::size_t limit) {
  return message.size() > limit || (!binary && !valid_utf8(message));
}

bool is_stop(const std::string& message, bool binary) {
  if (binary) return false;
  const rcand::JsonBody body = rcand::parse_json_body(message);  // how telemetry reads a message
  return body.error.empty() && body.value.is_object() && body.value.contains("cmd") && body.value["cmd"] == "stop";
}

void telemetry_message(const std::string& message, bool binary, std::size_t fragment) {
  for (int attempt = 0; attempt < 2; ++attempt) {  // a second try only after an unexplained close (a stalled reader)
    if (!telemetry().send(message, binary, fragment)) {
      if (may_close(message, binary, kTelemetryMaxMessage)) return;  // closed while the message was still going out
      continue;
    }
    for (;;) {
      const auto text = telemetry().read();
      if (!text) break;
      const json answer = json::parse(*text, nullptr, false);
      RCAND_FUZZ_CHECK(answer.is_object() && answer.contains("type"), "telemetry sends JSON objects with a type");
      if (answer["type"] == "telemetry") continue;
      if (answer["type"] == "stopped") {
        RCAND_FUZZ_CHECK(is_stop(message, binary), "only {\"cmd\":\"stop\"} stops");
        return;
      }
      RCAND_FUZZ_CHECK(answer["type"] == "error", "an answer is stopped or an error");
      RCAND_FUZZ_CHECK(answer.contains("code") && answer["code"].is_string() && !answer["code"].get<std::string>().empty() &&
                           answer.contains("error") && answer["error"].is_string(),
                       "a telemetry error has a code and a message");
      RCAND_FUZZ_CHECK(!is_stop(message, binary) || answer["code"] != "BAD_REQUEST", "a stop is not a bad request");
      return;
    }
    if (may_close(message, binary, kTelemetryMaxMessage)) return;
  }
  RCAND_FUZZ_CHECK(false, "telemetry closed twice on a message within its limits");
}

void check_r2r_frame(const std::string& text) {
  const auto parsed = rcand::r2r_wire::parse_envelope(text);
  const auto* envelope = std::get_if<rcand::r2r_wire::Envelope>(&parsed);
  RCAND_FUZZ_CHECK(envelope != nullptr, "the robot sends well-formed R2R messages");
  RCAND_FUZZ_CHECK(envelope->source_id == "fuzz-rover", "the robot sends as itself");
  if (envelope->type == rcand::r2r_wire::MessageType::Error) {
    const json code = envelope->payload.value("code", json());
    RCAND_FUZZ_CHECK(code.is_number_integer() && code.get<int>() >= 100 && code.get<int>() <= 105, "an R2R error code");
  }
}

void r2r_message(const std::string& message, bool binary, std::size_t fragment) {
  static double last_marker = 0;
  for (int attempt = 0; attempt < 2; ++attempt) {
    // After the input, a command the robot refuses (an action type it has none of), told apart by its timestamp,
    // which the error quotes back (ref): once that comes, the input was handled (one connection's messages are
    // handled in order). A refused command of an authenticated sender is always answered, where the refusals of
    // malformed or unauthenticated messages are rate-limited (docs/protocol.md §11.12) and would stall the run.
    const double now_s = std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
    const double marker = last_marker = std::max(now_s, last_marker + 1e-6);
    const std::string probe = json{
        {"header", {{"version", "1.0"}, {"timestamp", marker}, {"source_id", "fuzz-sync"}, {"target_id", "fuzz-rover"}}},
        {"type", "command"},
        {"payload",
         {{"type", "fuzz_sync"}}}}.dump();
    if (!r2r().send(message, binary, fragment) || !r2r().send(probe, false, 0)) {
      if (may_close(message, binary, kR2rMaxMessage)) return;  // closed while the message was still going out
      continue;
    }
    for (;;) {
      const auto text = r2r().read();
      if (!text) break;
      check_r2r_frame(*text);
      const json doc = json::parse(*text);
      const json ref = doc["payload"].value("ref", json::object());
      if (doc["type"] == "error" && ref.is_object() && ref.value("timestamp", json()) == marker) return;
    }
    if (may_close(message, binary, kR2rMaxMessage)) return;
  }
  RCAND_FUZZ_CHECK(false, "R2R closed twice on a message within its limits");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const std::string message(reinterpret_cast<const char*>(data) + 1, size - 1);
  const bool binary = (data[0] & 2) != 0;
  const std::size_t fragment = kFragments[(data[0] >> 2) & 7];
  if (data[0] & 1) r2r_message(message, binary, fragment);
  else telemetry_message(message, binary, fragment);
  rcand::fuzz::reset_robot();
  return 0;
}
