// One WS /ws/telemetry client, on the HTTP server's I/O thread that upgraded it (every member below runs there, so
// nothing in it needs a lock). It writes one message at a time: answers to the client's messages first, then the
// newest frame (a frame that arrives while one is being written waits in a single slot, replaced by a newer one).
// It reads the client's messages: {"cmd":"stop"} latches the e-stop through POST /api/stop's own row (the same
// middleware, audit entry and stop handler, run on this thread at once, never behind a frame being built); anything
// else is answered with an error message. Like R2R's sockets, it never outlives its credential: a JWT that expires
// or a token removed by a config reload closes it (1008).
#pragma once

#include <boost/beast/core/flat_buffer.hpp>
#include <boost/beast/websocket/stream.hpp>

#include <chrono>
#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "libs/http/upgrade.hpp"

namespace rcand::services::telemetry {

class TelemetryHub;

struct Credential {
  std::string bearer;  // as presented (header or ?token=); re-presented to POST /api/stop
  std::string principal;
  std::optional<std::int64_t> expires_s;
  std::uint64_t generation = 0;  // the authenticator's, when it was authorized
};

class Connection : public std::enable_shared_from_this<Connection> {
 public:
  // `slot` is released when the connection is destroyed (the hub's client count).
  Connection(std::weak_ptr<TelemetryHub> hub, http::UpgradeStream stream, std::string remote, Credential credential,
             std::shared_ptr<void> slot);

  void accept(boost::beast::http::request<boost::beast::http::string_body> raw);  // its I/O thread (the take hook)
  void offer(std::shared_ptr<const std::string> frame);                           // any thread
  void close();                                                                   // any thread: 1001 going away

 private:
  using Bytes = std::shared_ptr<const std::string>;
  void take_frame(Bytes frame);
  bool behind(std::size_t frame_bytes);
  void write_next();
  void read();
  void on_message(const std::string& text, bool binary);
  void request_stop(nlohmann::json body);  // POST /api/stop with this body, as this client
  void answer(const nlohmann::json& message);
  void error(std::string_view code, const std::string& message);
  bool credential_holds();
  void shut(std::optional<boost::beast::websocket::close_reason> reason);

  std::weak_ptr<TelemetryHub> hub_;
  boost::beast::websocket::stream<http::UpgradeStream> ws_;
  std::string remote_;
  Credential credential_;
  std::shared_ptr<void> slot_;
  boost::beast::flat_buffer buffer_;
  Bytes pending_;              // the newest frame not yet written
  std::deque<Bytes> answers_;  // replies to the client's messages, written before frames
  std::chrono::steady_clock::time_point write_started_;
  bool open_ = false, writing_ = false, closed_ = false;
};

}  // namespace rcand::services::telemetry
