#include "mqtt_broker.hpp"

#include <mosquitto.h>
#include <CLI/CLI.hpp>

#include <cerrno>
#include <cstring>
#include <fstream>

namespace rcand::rcanctl {
namespace {

std::optional<std::string> first_line(const std::filesystem::path& file) {
  std::ifstream in(file);
  std::string line;
  if (!in || !std::getline(in, line)) return std::nullopt;
  while (!line.empty() && (line.back() == '\r' || line.back() == ' ' || line.back() == '\t')) line.pop_back();
  if (line.empty()) return std::nullopt;
  return line;
}

template <typename T> void set_if_given(std::optional<T>& target, const std::string& flag) {
  if (!flag.empty()) target = flag;
}

}  // namespace

void MqttBrokerFlags::add_to(CLI::App& command, const std::string& mqtt_help, bool required, bool with_token_file) {
  command.add_option("--mqtt", broker_, mqtt_help)->required(required);
  command.add_option("--username", username_, "broker user name (runtime.r2r.mqtt.username)");
  command.add_option("--password-file", password_file_, "file holding the broker password (runtime.r2r.mqtt.password_file)");
  if (with_token_file)
    command.add_option("--token-file", token_file_,
                       "file holding a token sent as the broker password (runtime.r2r.mqtt.token_file)");
  command.add_option("--tls-ca-file", ca_file_,
                     "TLS to the broker: the CA its certificate chains to (runtime.r2r.mqtt.tls.ca_file)");
  command.add_option("--tls-cert-file", cert_file_, "mutual TLS: client certificate (runtime.r2r.mqtt.tls.cert_file)");
  command.add_option("--tls-key-file", key_file_, "mutual TLS: client key (runtime.r2r.mqtt.tls.key_file)");
}

std::optional<std::string> MqttBrokerFlags::apply(MqttBrokerOptions& options) const {
  if (!password_file_.empty() && !token_file_.empty()) return "give --password-file or --token-file, not both";
  if (cert_file_.empty() != key_file_.empty()) return "--tls-cert-file and --tls-key-file go together";
  if (!cert_file_.empty() && ca_file_.empty()) return "mutual TLS needs --tls-ca-file too";
  if (broker_.empty() && !(username_ + password_file_ + token_file_ + ca_file_).empty())
    return "the broker's user name, password and TLS flags need --mqtt";
  if (!username_.empty()) options.username = username_;
  set_if_given(options.password_file, password_file_);
  set_if_given(options.token_file, token_file_);
  set_if_given(options.ca_file, ca_file_);
  set_if_given(options.cert_file, cert_file_);
  set_if_given(options.key_file, key_file_);
  if (broker_.empty()) return std::nullopt;
  return split_broker_address(broker_, options);
}

std::optional<std::string> split_broker_address(const std::string& text, MqttBrokerOptions& options) {
  std::string host = text;
  std::optional<std::string> port;
  if (!host.empty() && host.front() == '[') {
    const auto close = host.find(']');
    if (close == std::string::npos) return "--mqtt: an IPv6 address needs its closing ']'";
    if (close + 1 < host.size()) {
      if (host[close + 1] != ':') return "--mqtt: expected HOST[:PORT]";
      port = host.substr(close + 2);
    }
    host = host.substr(1, close - 1);
  } else if (const auto colon = host.rfind(':'); colon != std::string::npos && host.find(':') == colon) {
    port = host.substr(colon + 1);
    host = host.substr(0, colon);
  }
  if (host.empty()) return "--mqtt: the broker host is empty";
  options.host = host;
  if (port) {
    int value = 0;
    try {
      std::size_t used = 0;
      value = std::stoi(*port, &used);
      if (used != port->size()) value = 0;
    } catch (...) {
      value = 0;
    }
    if (value < 1 || value > 65535) return "--mqtt: the port must be 1-65535, got '" + *port + "'";
    options.port = static_cast<std::uint16_t>(value);
  } else if (options.ca_file) {
    options.port = 8883;
  }
  return std::nullopt;
}

std::string configure_mosquitto(mosquitto* client, const MqttBrokerOptions& o) {
  std::optional<std::string> password;
  for (const auto* file : {&o.password_file, &o.token_file})
    if (*file && !(password = first_line(**file))) return "cannot read " + (*file)->string() + " (or it is empty)";
  mosquitto_int_option(client, MOSQ_OPT_PROTOCOL_VERSION, MQTT_PROTOCOL_V311);
  if (o.username || password) {
    const std::string user = o.username.value_or("rcanctl");
    if (mosquitto_username_pw_set(client, user.c_str(), password ? password->c_str() : nullptr) != MOSQ_ERR_SUCCESS)
      return "the broker user name was rejected by libmosquitto";
  }
  if (o.ca_file) {
    const std::string ca = o.ca_file->string();
    const std::string cert = o.cert_file ? o.cert_file->string() : std::string();
    const std::string key = o.key_file ? o.key_file->string() : std::string();
    if (const int rc = mosquitto_tls_set(client, ca.c_str(), nullptr, cert.empty() ? nullptr : cert.c_str(),
                                         key.empty() ? nullptr : key.c_str(), nullptr);
        rc != MOSQ_ERR_SUCCESS)
      return "TLS: " + mqtt_error_text(rc) + " (check the CA, certificate and key files)";
  }
  return "";
}

std::string mqtt_error_text(int rc) { return rc == MOSQ_ERR_ERRNO ? std::strerror(errno) : mosquitto_strerror(rc); }

}  // namespace rcand::rcanctl
