// R2R through an MQTT broker (docs/protocol.md §11.2) with libmosquitto: subscribes `r2r/<own name>` and
// `r2r/broadcast`, and the status topics it is told to (`status_subscriptions`); publishes a targeted message to
// `r2r/<target>`, this robot's `status` to `r2r/status/<own name>` (retained, QoS 0: the next one supersedes it; the
// last will says `offline` there, and stop() publishes it on a clean shutdown) and any other broadcast to
// `r2r/broadcast` (QoS 1). So status costs the broker one delivery per subscriber, not one per robot of the fleet.
// libmosquitto's own network thread does the I/O and reconnects with a growing delay; an outage is logged once when it
// starts and once when it ends. Passwords and tokens are read from files and never logged.
#pragma once

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <spdlog/logger.h>
#include <nlohmann/json.hpp>

#include "services/r2r/transport.hpp"

namespace rcand::services::r2r {

struct MqttTls {
  std::filesystem::path ca_file;                   // required for TLS
  std::optional<std::filesystem::path> cert_file;  // client certificate (with key_file): mutual TLS
  std::optional<std::filesystem::path> key_file;
};

struct MqttOptions {
  std::string robot_name;  // subscribes r2r/<robot_name>
  std::string host = "localhost";
  std::uint16_t port = 1883;
  std::optional<MqttTls> tls;
  std::optional<std::string> username;
  std::optional<std::filesystem::path> password_file;  // the password is the file's first line
  std::optional<std::filesystem::path> token_file;     // alternative: a token sent as the password
  std::string client_id;                               // empty: "rcand-<robot_name>"
  int keepalive_s = 30;
  std::string topic_prefix = "r2r";
  std::vector<std::string> extra_subscriptions;  // e.g. "r2r/#" for an observer (rcanctl r2r watch)
  // runtime.r2r.mqtt.status_subscriptions: the robots whose status this one reads (r2r/status/<name>), or all of them
  // (`all`: r2r/status/+, a fleet view). None by default: auctions need no one's status.
  std::vector<std::string> status_subscriptions;
  bool status_of_all = false;
  std::shared_ptr<spdlog::logger> log;  // null: spdlog's default logger
};

// Reads runtime.r2r.mqtt (relative files against base_dir). Throws std::invalid_argument naming the key at fault.
MqttOptions mqtt_options_from_config(const nlohmann::json& mqtt, const std::string& robot_name,
                                     const std::filesystem::path& base_dir);

struct MqttCounters {
  std::uint64_t published = 0, publish_failed = 0, received = 0, connects = 0, disconnects = 0;
};

class MqttTransport : public Transport {
 public:
  explicit MqttTransport(MqttOptions options);
  ~MqttTransport() override;  // stop()

  std::string_view name() const noexcept override { return "mqtt"; }
  // Connects in the background (a broker that is down is retried, not fatal). Throws std::runtime_error naming the
  // setting for what can never work: unreadable password/token/TLS files, a client that cannot be created.
  void start(Deliver deliver) override;
  // Queues the publish; false when not started or libmosquitto refuses it (never because the broker is down:
  // QoS 1 messages wait for the reconnect).
  bool send(const std::string& bytes, const std::optional<std::string>& target_id) override;
  // Publishes `offline()` retained on r2r/status/<own name> before it disconnects (a clean shutdown sends no will).
  void stop() noexcept override;
  void set_offline_status(std::function<std::string()> offline) override;

  bool connected() const noexcept;
  MqttCounters counters() const;

  struct State;

 private:
  std::shared_ptr<State> state_;
};

}  // namespace rcand::services::r2r
