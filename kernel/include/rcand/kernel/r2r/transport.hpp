// The one interface behind which every R2R transport lives (WebSocket, UDP, MQTT): bytes in, bytes out.
// Transports never interpret R2R; the node parses, authenticates and dispatches. Plugins never see a transport.
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <string_view>

#include "rcand/kernel/auth/authenticator.hpp"

namespace rcand::kernel::r2r {

// One message as it arrived, with what the transport knows about its sender.
struct InboundMessage {
  std::string bytes;
  std::string transport;  // "ws" | "udp" | "mqtt" | "local" (tests)
  std::string peer;       // remote address:port (ws, udp) or the MQTT topic it arrived on
  // Set when the transport itself authenticated the sender (a WebSocket upgrade with a bearer token, like HTTP).
  std::optional<Principal> principal;
  // Sends bytes back to this sender on the same transport (WebSocket: the same connection); empty when the
  // transport cannot answer one sender (UDP broadcasts: answers go out through send()).
  std::function<void(std::string bytes)> reply;
};

// Called on the transport's own thread; must not block.
using Deliver = std::function<void(InboundMessage)>;

class Transport {
 public:
  virtual ~Transport() = default;
  virtual std::string_view name() const noexcept = 0;
  // Starts receiving. Throws std::runtime_error naming the setting at fault when it cannot start.
  virtual void start(Deliver deliver) = 0;
  // Queues bytes for target_id (a robot name), or for every peer when nullopt. Never blocks. False when this
  // transport cannot reach the target (for example an unknown peer), so the node can try the next transport.
  virtual bool send(const std::string& bytes, const std::optional<std::string>& target_id) = 0;
  // Stops receiving and sending; idempotent. No Deliver call runs after it returns.
  virtual void stop() noexcept = 0;
};

}  // namespace rcand::kernel::r2r
