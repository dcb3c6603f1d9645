// One MQTT publish that waits for the broker's acknowledgement (QoS 1 PUBACK): what `rcanctl fleet stop --mqtt` needs
// to say "the broker has it" and exit 0. libmosquitto does the protocol; every wait is bounded by options.timeout.
#pragma once

#include <cstdint>
#include <string>

#include "mqtt_broker.hpp"

namespace rcand::rcanctl {

struct MqttPublishResult {
  bool acknowledged = false;
  std::string error;  // why not, when not
  std::int64_t elapsed_ms = 0;
};

// Connects, publishes `payload` on `topic` with QoS 1 (not retained), waits for the PUBACK, disconnects.
MqttPublishResult mqtt_publish_once(const MqttBrokerOptions& options, const std::string& topic, const std::string& payload);

}  // namespace rcand::rcanctl
