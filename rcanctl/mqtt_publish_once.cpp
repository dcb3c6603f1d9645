#include "mqtt_publish_once.hpp"

#include <mosquitto.h>

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

}  // namespace

MqttPublishResult mqtt_publish_once(const MqttBrokerOptions& o, const std::string& topic, const std::string& payload) {
  MqttPublishResult result;
  const auto started = std::chrono::steady_clock::now();
  const auto deadline = started + o.timeout;
  auto finish = [&](std::string error) {
    result.error = std::move(error);
    result.elapsed_ms = std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::steady_clock::now() - started).count();
    return result;
  };
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
  if (auto failed = configure_mosquitto(client, o); !failed.empty()) return finish(failed);
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
    return finish("cannot reach the broker " + where + ": " + mqtt_error_text(rc));
  auto loop_until = [&](const bool& done) {
    while (!done && !progress.refused && std::chrono::steady_clock::now() < deadline)
      if (const int rc = mosquitto_loop(client, 50, 1); rc != MOSQ_ERR_SUCCESS) return mqtt_error_text(rc);
    return std::string();
  };
  if (auto failed = loop_until(progress.connected); !failed.empty()) return finish("broker " + where + ": " + failed);
  if (progress.refused) return finish("the broker " + where + " refused the connection: " + progress.refusal);
  if (!progress.connected) return finish("no answer from the broker " + where + " within the timeout");
  if (const int rc =
          mosquitto_publish(client, &progress.mid, topic.c_str(), static_cast<int>(payload.size()), payload.data(), 1, false);
      rc != MOSQ_ERR_SUCCESS)
    return finish("publish refused by libmosquitto: " + mqtt_error_text(rc));
  if (auto failed = loop_until(progress.acknowledged); !failed.empty()) return finish("broker " + where + ": " + failed);
  if (!progress.acknowledged) return finish("the broker " + where + " did not acknowledge the message within the timeout");
  mosquitto_disconnect(client);
  mosquitto_loop(client, 50, 1);  // the DISCONNECT goes out
  result.acknowledged = true;
  return finish("");
}

}  // namespace rcand::rcanctl
