// A test's own MQTT client on a real broker (the MqttTransport robots use): keeps every JSON object it receives,
// with its topic, for the test to wait on and count. What the R2R tests over mosquitto see on the wire.
#pragma once

#include <algorithm>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "eventually.hpp"
#include "r2r_lab.hpp"
#include "services/r2r/transports/mqtt_transport.hpp"

namespace rcand::test {

// A client named `name` of the broker on 127.0.0.1:`port` (keepalive 5 s), also subscribed to `subscriptions`.
inline services::r2r::MqttOptions mqtt_client(const std::string& name, std::uint16_t port,
                                              std::vector<std::string> subscriptions = {}) {
  services::r2r::MqttOptions options;
  options.robot_name = name;
  options.host = "127.0.0.1";
  options.port = port;
  options.keepalive_s = 5;
  options.extra_subscriptions = std::move(subscriptions);
  return options;
}

// A string field of a message as seen on the wire, "" when absent or of another type (operator[] on a const json
// with a missing key is undefined: ASan caught it on an intruder's message without the field).
inline std::string wire_field(const nlohmann::json& m, const char* pointer) {
  const nlohmann::json::json_pointer at(pointer);
  return m.is_object() && m.contains(at) && m.at(at).is_string() ? m.at(at).get<std::string>() : std::string();
}

class MqttWatch {
 public:
  using Match = std::function<bool(const std::string& topic, const nlohmann::json& message)>;

  explicit MqttWatch(services::r2r::MqttOptions options) : transport_(std::move(options)) {
    transport_.start([this](services::r2r::InboundMessage message) {
      auto parsed = nlohmann::json::parse(message.bytes, nullptr, false);
      if (!parsed.is_object()) return;  // no R2R message: nothing a test matches
      std::lock_guard lock(mutex_);
      seen_.emplace_back(message.peer, std::move(parsed));
    });
  }
  ~MqttWatch() { transport_.stop(); }
  MqttWatch(const MqttWatch&) = delete;
  MqttWatch& operator=(const MqttWatch&) = delete;

  services::r2r::MqttTransport& transport() { return transport_; }
  bool connected(std::chrono::milliseconds timeout = std::chrono::seconds(10)) {
    return eventually([&] { return transport_.connected(); }, timeout);
  }

  // The JSON objects received so far that match (topic, message).
  std::vector<nlohmann::json> matching(const Match& match) {
    std::lock_guard lock(mutex_);
    std::vector<nlohmann::json> found;
    for (const auto& [topic, message] : seen_)
      if (match(topic, message)) found.push_back(message);
    return found;
  }
  std::size_t count(const Match& match) {
    std::lock_guard lock(mutex_);
    return static_cast<std::size_t>(
        std::count_if(seen_.begin(), seen_.end(), [&](const auto& entry) { return match(entry.first, entry.second); }));
  }

  // The first message (topic, message) that matches, within the timeout.
  std::optional<std::pair<std::string, nlohmann::json>> wait_for(const Match& match,
                                                                 std::chrono::milliseconds timeout = std::chrono::seconds(10)) {
    return poll_until<std::pair<std::string, nlohmann::json>>(
        [&]() -> std::optional<std::pair<std::string, nlohmann::json>> {
          std::lock_guard lock(mutex_);
          for (const auto& entry : seen_)
            if (match(entry.first, entry.second)) return entry;
          return std::nullopt;
        },
        timeout);
  }

 private:
  std::mutex mutex_;
  std::vector<std::pair<std::string, nlohmann::json>> seen_;
  services::r2r::MqttTransport transport_;
};

// Matches the messages of R2R `type` sent by `source`.
inline MqttWatch::Match r2r_sent(const std::string& type, const std::string& source) {
  return [type, source](const std::string&, const nlohmann::json& m) {
    return wire_field(m, "/type") == type && wire_field(m, "/header/source_id") == source;
  };
}
inline MqttWatch::Match r2r_type(const std::string& type) {
  return [type](const std::string&, const nlohmann::json& m) { return wire_field(m, "/type") == type; };
}

}  // namespace rcand::test
