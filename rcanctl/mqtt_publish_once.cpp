#include "mqtt_publish_once.hpp"

#include <mosquitto.h>

#include <cerrno>
#include <cstring>
#include <fstream>

namespace rcand::rcanctl {
namespace {

// What the callbacks learn; libmosquitto calls them from mosquitto_loop() on this thread.
struct PublishProgress {
  bool connected = false;
  bool refused = false;
  std::string refusal;
  int mid = -1;
  bool acknowledged = false;
};

std::optional<std::string> publish_first_line(const std::filesystem::path& file) {
  std::ifstream in(file);
  std::string line;
  if (!in || !std::getline(in, line)) return std::nullopt;
  while (!line.empty() && (line.back() == '\r' || line.back() == ' ' || line.back() == '\t')) line.pop_back();
  if (line.empty()) return std::nullopt;
  return line;
}

std::string publish_error_text(int rc) { return rc == MOSQ_ERR_ERRNO ? std::strerror(errno) : mosquitto_strerror(rc); }

}  // namespace

MqttPublishResult mqtt_publish_once(const MqttPublishOptions& o, const std::string& topic, const std::string& payload) {
  MqttPublishResult result;
  const auto started = std::chrono::steady_clock::now();
  const auto deadline = started + o.timeout;
  auto finish = [&](std::string error) {
    result.error = std::move(error);
    result.elapsed_ms = std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::steady_clock::now() - started).count();
    return result;
  };
  std::optional<std::string> password;
  for (const auto* file : {&o.password_file, &o.token_file})
    if (*file && !(password = publish_first_line(**file)))
      return finish("cannot read " + (*file)->string() + " (or it is empty)");

  mosquitto_lib_init();
  PublishProgress progress;
  mosquitto* client = mosquitto_new(o.client_id.empty() ? nullptr : o.client_id.c_str(), true, &progress);
  if (client == nullptr) return finish("cannot create an MQTT client");
  struct Destroy {
    mosquitto* client;
    ~Destroy() {
      mosquitto_destroy(client);
      mosquitto_lib_cleanup();
    }
  } destroy{client};
  mosquitto_int_option(client, MOSQ_OPT_PROTOCOL_VERSION, MQTT_PROTOCOL_V311);
  if (o.username || password) {
    const std::string user = o.username.value_or("rcanctl");
    if (mosquitto_username_pw_set(client, user.c_str(), password ? password->c_str() : nullptr) != MOSQ_ERR_SUCCESS)
      return finish("the broker user name was rejected by libmosquitto");
  }
  if (o.ca_file) {
    const std::string ca = o.ca_file->string();
    const std::string cert = o.cert_file ? o.cert_file->string() : std::string();
    const std::string key = o.key_file ? o.key_file->string() : std::string();
    if (const int rc = mosquitto_tls_set(client, ca.c_str(), nullptr, cert.empty() ? nullptr : cert.c_str(),
                                         key.empty() ? nullptr : key.c_str(), nullptr);
        rc != MOSQ_ERR_SUCCESS)
      return finish("TLS: " + publish_error_text(rc) + " (check the CA, certificate and key files)");
  }
  mosquitto_connect_callback_set(client, [](mosquitto*, void* self, int rc) {
    auto& p = *static_cast<PublishProgress*>(self);
    if (rc == 0) p.connected = true;
    else {
      p.refused = true;
      p.refusal = mosquitto_connack_string(rc);
    }
  });
  mosquitto_publish_callback_set(client, [](mosquitto*, void* self, int mid) {
    auto& p = *static_cast<PublishProgress*>(self);
    if (mid == p.mid) p.acknowledged = true;
  });
  const std::string where = o.host + ":" + std::to_string(o.port);
  // Asynchronous: a blocking connect to a host that drops the SYN (a full backlog, a firewall) waits for the kernel's
  // SYN retries, two minutes, whatever --timeout says; this one goes on in mosquitto_loop, within the deadline.
  if (const int rc = mosquitto_connect_async(client, o.host.c_str(), o.port, 30); rc != MOSQ_ERR_SUCCESS)
    return finish("cannot reach the broker " + where + ": " + publish_error_text(rc));
  auto loop_until = [&](const bool& done) {
    while (!done && !progress.refused && std::chrono::steady_clock::now() < deadline)
      if (const int rc = mosquitto_loop(client, 50, 1); rc != MOSQ_ERR_SUCCESS) return publish_error_text(rc);
    return std::string();
  };
  if (auto failed = loop_until(progress.connected); !failed.empty()) return finish("broker " + where + ": " + failed);
  if (progress.refused) return finish("the broker " + where + " refused the connection: " + progress.refusal);
  if (!progress.connected) return finish("no answer from the broker " + where + " within the timeout");
  if (const int rc =
          mosquitto_publish(client, &progress.mid, topic.c_str(), static_cast<int>(payload.size()), payload.data(), 1, false);
      rc != MOSQ_ERR_SUCCESS)
    return finish("publish refused by libmosquitto: " + publish_error_text(rc));
  if (auto failed = loop_until(progress.acknowledged); !failed.empty()) return finish("broker " + where + ": " + failed);
  if (!progress.acknowledged) return finish("the broker " + where + " did not acknowledge the message within the timeout");
  mosquitto_disconnect(client);
  mosquitto_loop(client, 50, 1);  // the DISCONNECT goes out
  result.acknowledged = true;
  return finish("");
}

}  // namespace rcand::rcanctl
