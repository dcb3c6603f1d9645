// How rcanctl reaches a fleet's MQTT broker (fleet stop, r2r watch --mqtt): the connection options a robot takes in
// runtime.r2r.mqtt (user name, password or token file, TLS), as the flags an operator passes, applied to a libmosquitto
// client. So an operator reaches the broker the way the robots do.
#pragma once

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>

struct mosquitto;
namespace CLI {
class App;
}

namespace rcand::rcanctl {

struct MqttBrokerOptions {
  std::string host = "localhost";
  std::uint16_t port = 1883;
  std::optional<std::string> username;
  std::optional<std::filesystem::path> password_file;        // the password is the file's first line
  std::optional<std::filesystem::path> token_file;           // alternative: a token sent as the password
  std::optional<std::filesystem::path> ca_file;              // TLS (the broker's certificate must chain to it)
  std::optional<std::filesystem::path> cert_file, key_file;  // mutual TLS
  std::string client_id;
  std::chrono::milliseconds timeout{10000};  // reaching the broker (and, for a publish, its acknowledgement)
};

// One command's broker flags: --mqtt HOST[:PORT], --username, --password-file, --token-file, --tls-ca-file,
// --tls-cert-file, --tls-key-file. A command whose --token-file is the robot's (r2r watch) goes without the broker's:
// a token sent as the broker password is a password file.
class MqttBrokerFlags {
 public:
  void add_to(CLI::App& command, const std::string& mqtt_help, bool required, bool with_token_file = true);
  bool given() const noexcept { return !broker_.empty(); }
  // Checks the flags together and fills `options`; the port is 1883, or 8883 with TLS, unless given. Returns the usage
  // error when they are wrong.
  std::optional<std::string> apply(MqttBrokerOptions& options) const;

 private:
  std::string broker_, username_, password_file_, token_file_, ca_file_, cert_file_, key_file_;
};

// "HOST[:PORT]" (an IPv6 address in brackets: "[::1]:1883") into options.host and options.port; the error, if any.
std::optional<std::string> split_broker_address(const std::string& text, MqttBrokerOptions& options);

// Sets MQTT 3.1.1, the credentials and TLS of `options` on `client`. Returns what went wrong, empty when nothing did.
std::string configure_mosquitto(mosquitto* client, const MqttBrokerOptions& options);

// libmosquitto's error text for `rc` (errno's for MOSQ_ERR_ERRNO).
std::string mqtt_error_text(int rc);

}  // namespace rcand::rcanctl
