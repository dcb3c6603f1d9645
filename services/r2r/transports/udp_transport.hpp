// R2R `status` broadcasts over UDP on the LAN (docs/protocol.md §11): one message per datagram, sent to a configured list of
// destinations (255.255.255.255, a subnet broadcast address, or explicit peers), received on
// runtime.r2r.udp_port (default: the robot's RCAN port). Only `status` goes out this way (it is best-effort by
// nature and superseded by the next one); everything else needs WebSocket or MQTT. Datagrams carry no reply route.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <spdlog/logger.h>
#include <nlohmann/json.hpp>

#include "services/r2r/transport.hpp"

namespace rcand::services::r2r {

struct UdpDestination {
  std::string host;        // an IPv4/IPv6 address (resolved once at start)
  std::uint16_t port = 0;  // 0: the transport's own port (every robot of the fleet listens on the same one)
};

struct UdpOptions {
  std::string bind_address = "0.0.0.0";
  std::uint16_t port = 0;  // 0: any free port (tests)
  std::vector<UdpDestination> destinations;
  std::size_t max_datagram_bytes = 64 * 1024;  // larger ones are not sent (and cannot arrive over IPv4)
  std::shared_ptr<spdlog::logger> log;
};

// "255.255.255.255", "10.0.0.7:9100", "[fe80::1]:9100" -> destination; throws std::invalid_argument naming `key`.
UdpDestination parse_udp_destination(const std::string& text, const std::string& key);

struct UdpCounters {
  std::uint64_t sent = 0, send_failed = 0, received = 0;
};

class UdpTransport : public Transport {
 public:
  explicit UdpTransport(UdpOptions options);
  ~UdpTransport() override;

  std::string_view name() const noexcept override { return "udp"; }
  // Binds and starts the receive thread. Throws std::runtime_error "runtime.r2r.udp_port: cannot bind ...".
  void start(Deliver deliver) override;
  // Broadcast `status` messages only; false for a target or another type.
  bool send(const std::string& bytes, const std::optional<std::string>& target_id) override;
  void stop() noexcept override;

  std::uint16_t bound_port() const noexcept;
  UdpCounters counters() const;

  struct State;

 private:
  std::shared_ptr<State> state_;
};

}  // namespace rcand::services::r2r
