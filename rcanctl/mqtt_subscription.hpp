// `rcanctl r2r watch --mqtt`: every message on a topic filter of the fleet's broker, delivered on libmosquitto's network
// thread, which reconnects after an outage (the subscription is renewed on every connect).
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <string_view>

#include "mqtt_broker.hpp"

namespace rcand::rcanctl {

class MqttSubscription {
 public:
  using OnMessage = std::function<void(std::string_view topic, std::string_view payload)>;
  // Connects and subscribes `filter` (QoS 1); returns once the broker has acknowledged the subscription. Throws
  // std::runtime_error naming the broker and what went wrong when that does not happen within options.timeout.
  MqttSubscription(const MqttBrokerOptions& options, std::string filter, OnMessage on_message);
  ~MqttSubscription();  // disconnects; no callback runs after it returns
  MqttSubscription(const MqttSubscription&) = delete;
  MqttSubscription& operator=(const MqttSubscription&) = delete;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace rcand::rcanctl
