// R2R over WebSocket (docs/protocol.md §11): `WS /ws/r2r` on the robot's own HTTP port, authenticated like HTTP (a bearer token
// or JWT on the upgrade request, or ?token=; 401 without), one R2R message per text frame. Peers that connect are
// addressable by the source_id they announce in their messages; peers listed in swarm.yaml are dialed (with the
// node's token from swarm.yaml; wss for a node with `ca`) when a message must reach them and they are not connected. Inbound and
// dialed connections are the same kind of object: a read loop, a write queue (one async_write at a time), keep-alive pings and an
// idle timeout; a frame over 64 KiB closes the connection with 1009 (Beast's read_message_max).
#pragma once

#include <chrono>
#include <cstddef>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <spdlog/logger.h>
#include <nlohmann/json.hpp>

#include "kernel/auth/authenticator.hpp"
#include "libs/http/server_options.hpp"
#include "libs/swarm/swarm_registry.hpp"
#include "services/r2r/transport.hpp"

namespace rcand::services::r2r {

inline constexpr std::string_view kWebSocketPath = "/ws/r2r";

struct WebSocketOptions {
  std::string self_name;  // never dialed, even when swarm.yaml lists it
  // The swarm.yaml robots this one dials when a message must reach them, as the registry is now (a SIGHUP reload swaps
  // it; a registry stays alive while rcand serves). Unset: this robot never dials (MQTT carries what WS cannot).
  std::function<const swarm::SwarmRegistry*()> dial_peers;
  std::size_t max_message_bytes = 64 * 1024;
  std::chrono::milliseconds idle_timeout{30'000};      // no frame (pongs count) this long: closed; pings at half
  std::chrono::milliseconds handshake_timeout{5'000};  // dial: connect + upgrade
  std::chrono::milliseconds redial_backoff{2'000};     // after a failed dial, messages to that peer are refused
  std::size_t max_connections = 256;                   // inbound; beyond it the upgrade answers 503 UNAVAILABLE
  std::size_t max_connections_per_principal = 8;       // inbound sockets one principal below OWNER may hold (429)
  std::size_t max_connections_per_address = 16;        // inbound sockets principals below OWNER may hold from one address (429)
  std::size_t reserved_connections = 32;               // of max_connections, only for OWNER and CREATOR (503)
  std::size_t max_queued_bytes = 1024 * 1024;          // per connection; beyond it (a peer that does not read) dropped
  std::shared_ptr<spdlog::logger> log;                 // null: spdlog's default logger
};

// The runtime.r2r keys of the WebSocket transport (validated by the config schema): ws_max_connections,
// ws_max_connections_per_principal, ws_max_connections_per_address, ws_reserved_connections, ws_max_queued_bytes. Absent keys
// keep `options`' values.
void apply_websocket_config(const nlohmann::json& r2r_block, WebSocketOptions& options);

struct WebSocketCounters {
  std::uint64_t inbound_accepted = 0, inbound_refused = 0, dialed = 0, dial_failed = 0, frames_in = 0, frames_out = 0,
                closed_oversize = 0, closed_credentials = 0;
};

class WebSocketTransport : public Transport {
 public:
  // `authenticator` authorizes upgrades; it must outlive the transport.
  WebSocketTransport(WebSocketOptions options, const kernel::Authenticator& authenticator);
  ~WebSocketTransport() override;  // stop()

  // The HTTP server's ServerOptions::upgrade hook: takes GET /ws/r2r (401 without valid credentials, 503 when not
  // started or full), leaves every other path to the Handler. Safe to call before start() and after stop().
  http::UpgradeHandler upgrade_handler();

  std::string_view name() const noexcept override { return "ws"; }
  void start(Deliver deliver) override;
  bool send(const std::string& bytes, const std::optional<std::string>& target_id) override;
  // `with_token` to dialed peers and to clients of OWNER rank; `open` to every other connection.
  bool send_own(const std::string& with_token, const std::string& open, const std::optional<std::string>& target_id) override;
  void stop() noexcept override;

  // {"connections":[{"peer","name","direction","queued"}]}: for GET /api/r2r/peers.
  nlohmann::json connections() const;
  WebSocketCounters counters() const;

  struct Hub;  // shared with every connection, which may outlive the transport on an event loop's queue

 private:
  std::shared_ptr<Hub> hub_;
};

}  // namespace rcand::services::r2r
