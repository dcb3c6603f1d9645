// The one interface behind which every R2R transport lives (WebSocket, UDP, MQTT): bytes in, bytes out.
// Transports never interpret R2R; the node parses, authenticates and dispatches. Plugins never see a transport.
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <string_view>

#include "kernel/auth/authenticator.hpp"

namespace rcand::services::r2r {

// One message as it arrived, with what the transport knows about its sender.
struct InboundMessage {
  std::string bytes;
  std::string transport;  // "ws" | "udp" | "mqtt" | "local" (tests)
  std::string peer;       // remote address:port (ws, udp) or the MQTT topic it arrived on
  // Set when the transport itself authenticated the sender (a WebSocket upgrade with a bearer token, like HTTP).
  std::optional<kernel::Principal> principal;
  // Sends bytes back to this sender on the same transport (WebSocket: the same connection); empty when the
  // transport cannot answer one sender (UDP broadcasts: answers go out through send()).
  std::function<void(std::string bytes)> reply;
  // False when the sender may not see this robot's bearer token in an answer (a WebSocket client below OWNER: a
  // guest watching the fleet must not learn the credential this robot acts with).
  bool trusted_with_secrets = true;
  // Arrived as a broadcast (MQTT r2r/broadcast or r2r/status/<name>, any UDP datagram): never answered with an `error`
  // (docs/protocol.md §11.12) - N robots would answer each other N·(N-1) times.
  bool broadcast = false;
  // Arrived on the sender's own status topic (MQTT r2r/status/<name>): a retained copy or a last will may be older
  // than the replay window (docs/protocol.md §11.13).
  bool status_topic = false;
};

// A transport that may carry this robot's bearer token (header.auth.token): a WebSocket has an authenticated peer at
// each end (and "local" is the in-process test network). UDP datagrams and MQTT publishes go to a broadcast address
// or through a broker to every subscriber: they never carry it (issue 13 #10) - sign instead (private_key_file).
inline bool transport_may_carry_secrets(std::string_view transport) { return transport == "ws" || transport == "local"; }

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
  // A message of this robot's in two spellings: `with_token` carries its bearer token, `open` does not. By default
  // a transport that may carry secrets sends `with_token`, any other `open`; the WebSocket transport chooses per
  // connection (only peers trusted with it get the token).
  virtual bool send_own(const std::string& with_token, const std::string& open, const std::optional<std::string>& target_id) {
    return send(transport_may_carry_secrets(name()) ? with_token : open, target_id);
  }
  // A transport that keeps each robot's last status on a topic of its own (MQTT: retained r2r/status/<name>) leaves
  // `offline()` there when this robot goes away: as its last will when the broker loses it, published by stop() on a
  // clean shutdown. Set before start(); any thread may call it; it must not block. Others ignore it.
  virtual void set_offline_status(std::function<std::string()> offline) { (void)offline; }
  // Stops receiving and sending; idempotent. No Deliver call runs after it returns.
  virtual void stop() noexcept = 0;
};

}  // namespace rcand::services::r2r
