// One MQTT publish that waits for the broker's acknowledgement (QoS 1 PUBACK): what `rcanctl fleet stop --mqtt` needs
// to say "the broker has it" and exit 0. The connection options are runtime.r2r.mqtt's (user name, password or token
// file, TLS), so an operator passes what the robots use. libmosquitto does the protocol; every wait is bounded.
#pragma once

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>

namespace rcand::rcanctl {

struct MqttPublishOptions {
  std::string host = "localhost";
  std::uint16_t port = 1883;
  std::optional<std::string> username;
  std::optional<std::filesystem::path> password_file;        // the password is the file's first line
  std::optional<std::filesystem::path> token_file;           // alternative: a token sent as the password
  std::optional<std::filesystem::path> ca_file;              // TLS (the broker's certificate must chain to it)
  std::optional<std::filesystem::path> cert_file, key_file;  // mutual TLS
  std::string client_id;
  std::chrono::milliseconds timeout{10000};  // connect + publish + acknowledgement
};

struct MqttPublishResult {
  bool acknowledged = false;
  std::string error;  // why not, when not
  std::int64_t elapsed_ms = 0;
};

// Connects, publishes `payload` on `topic` with QoS 1 (not retained), waits for the PUBACK, disconnects.
MqttPublishResult mqtt_publish_once(const MqttPublishOptions& options, const std::string& topic, const std::string& payload);

}  // namespace rcand::rcanctl
