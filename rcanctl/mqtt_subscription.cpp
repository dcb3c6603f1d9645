#include "mqtt_subscription.hpp"

#include <mosquitto.h>

#include <condition_variable>
#include <mutex>
#include <stdexcept>

namespace rcand::rcanctl {

struct MqttSubscription::State {
  std::string filter;
  OnMessage on_message;
  mosquitto* client = nullptr;
  std::mutex mutex;
  std::condition_variable changed;
  bool subscribed = false;
  std::string refusal;  // the broker's CONNACK refusal, when it refused
};

MqttSubscription::MqttSubscription(const MqttBrokerOptions& options, std::string filter, OnMessage on_message)
    : state_(std::make_unique<State>()) {
  State& s = *state_;
  s.filter = std::move(filter);
  s.on_message = std::move(on_message);
  const std::string where = options.host + ":" + std::to_string(options.port);
  mosquitto_lib_init();
  s.client = mosquitto_new(options.client_id.empty() ? nullptr : options.client_id.c_str(), true, &s);
  auto fail = [&](const std::string& why) {
    if (s.client != nullptr) {
      mosquitto_loop_stop(s.client, true);
      mosquitto_destroy(s.client);
    }
    mosquitto_lib_cleanup();
    throw std::runtime_error(why);
  };
  if (s.client == nullptr) fail("cannot create an MQTT client");
  if (auto failed = configure_mosquitto(s.client, options); !failed.empty()) fail(failed);
  mosquitto_connect_callback_set(s.client, [](mosquitto* client, void* self, int rc) {
    auto& state = *static_cast<State*>(self);
    if (rc == 0) {
      mosquitto_subscribe(client, nullptr, state.filter.c_str(), 1);
      return;
    }
    std::lock_guard lock(state.mutex);
    state.refusal = mosquitto_connack_string(rc);
    state.changed.notify_all();
  });
  mosquitto_subscribe_callback_set(s.client, [](mosquitto*, void* self, int, int, const int*) {
    auto& state = *static_cast<State*>(self);
    std::lock_guard lock(state.mutex);
    state.subscribed = true;
    state.changed.notify_all();
  });
  mosquitto_message_callback_set(s.client, [](mosquitto*, void* self, const mosquitto_message* message) {
    auto& state = *static_cast<State*>(self);
    state.on_message(message->topic ? message->topic : "",
                     std::string_view(static_cast<const char*>(message->payload), static_cast<std::size_t>(message->payloadlen)));
  });
  mosquitto_reconnect_delay_set(s.client, 1, 30, true);
  // Asynchronous, like the publish: a host that drops the SYN must not hold the command past options.timeout.
  if (const int rc = mosquitto_connect_async(s.client, options.host.c_str(), options.port, 30); rc != MOSQ_ERR_SUCCESS)
    fail("cannot reach the broker " + where + ": " + mqtt_error_text(rc));
  if (const int rc = mosquitto_loop_start(s.client); rc != MOSQ_ERR_SUCCESS) fail("MQTT network thread: " + mqtt_error_text(rc));
  std::unique_lock lock(s.mutex);
  s.changed.wait_for(lock, options.timeout, [&] { return s.subscribed || !s.refusal.empty(); });
  if (s.subscribed) return;
  const std::string refusal = s.refusal;
  lock.unlock();
  fail(refusal.empty() ? "no answer from the broker " + where + " within the timeout"
                       : "the broker " + where + " refused the connection: " + refusal);
}

MqttSubscription::~MqttSubscription() {
  mosquitto_disconnect(state_->client);
  mosquitto_loop_stop(state_->client, false);
  mosquitto_destroy(state_->client);
  mosquitto_lib_cleanup();
}

}  // namespace rcand::rcanctl
