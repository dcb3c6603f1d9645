// WS /ws/telemetry's clients and its one clock. A ticker thread ("telemetry") builds one frame every period and
// hands the same bytes to every client; an e-stop latch or clear (signal(), from the e-stop listeners) wakes it to
// push a frame at once, off the stop path. Each client holds at most one frame waiting behind the one being
// written (a newer one replaces it), and one whose socket backlog grows past a few frames, or whose write stalls,
// is dropped: a slow client costs the others nothing and the robot a bounded amount of memory.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <string_view>
#include <thread>

#include "kernel/api/api.hpp"
#include "kernel/auth/authenticator.hpp"
#include "libs/base/slot_table.hpp"
#include "libs/http/server_options.hpp"

namespace rcand::services::telemetry {

class Connection;

struct HubOptions {
  std::chrono::milliseconds period{200};  // docs/protocol.md §7.10
  std::size_t max_clients = 256;          // beyond: the upgrade answers 503
  // The slots (kernel/auth/slot_holder.hpp): of max_clients the last reserved_clients are OWNER's and CREATOR's (503
  // SLOTS_RESERVED to others); a principal below OWNER holds at most max_clients_per_principal, and such principals at
  // most max_clients_per_address from one address (429 TOO_MANY_CONNECTIONS).
  std::size_t reserved_clients = 32;
  std::size_t max_clients_per_principal = 8;
  std::size_t max_clients_per_address = 16;
  // A client is dropped once the bytes its socket has not delivered exceed both of these: about two seconds of
  // frames, and never less than min_backlog_bytes (so a brief network stall is not a drop).
  std::size_t backlog_frames = 10;
  std::size_t min_backlog_bytes = 8192;
  std::chrono::milliseconds write_stall{2000};  // one frame's write taking longer: dropped
  std::size_t max_message_bytes = 4096;         // a client's message; larger closes it (1009)
};

// Counters for /metrics; every field only grows, except clients.
struct HubCounters {
  std::uint64_t clients = 0, accepted = 0, refused = 0, frames_built = 0, frames_sent = 0, frames_replaced = 0;
  std::uint64_t dropped_slow = 0, closed_credential = 0, stops = 0, bad_messages = 0;
};

enum class HubEvent : unsigned { Latched = 1, Cleared = 2 };

class TelemetryHub : public std::enable_shared_from_this<TelemetryHub> {
 public:
  // Builds one frame's bytes: `seq` and `event` ("tick", "estop_latched", "estop_cleared") go into it.
  using BuildFrame = std::function<std::string(std::uint64_t seq, std::string_view event)>;

  TelemetryHub(HubOptions options, const kernel::Authenticator& auth, kernel::Api& api, BuildFrame build);
  ~TelemetryHub();  // stop()

  // The server's upgrade hook: takes /ws/telemetry (401/403 as HTTP refusals, 503 when full or stopped), and returns
  // an empty verdict for every other path so the next hook may serve it.
  http::UpgradeHandler upgrade_handler();
  void start();  // the ticker
  // No frame is built or sent afterwards; every client is closed. Idempotent.
  void stop() noexcept;
  // The e-stop listeners: sets a flag and wakes the ticker (a lock held for a few instructions); never builds.
  void signal(HubEvent event) noexcept;
  HubCounters counters() const;

  // For connections (telemetry_connection.cpp).
  const HubOptions& options() const noexcept { return options_; }
  const kernel::Authenticator& auth() const noexcept { return auth_; }
  kernel::Api& api() noexcept { return api_; }
  void closed(const std::shared_ptr<Connection>& connection) noexcept;
  struct Atomics {
    std::atomic<std::uint64_t> accepted{0}, refused{0}, frames_built{0}, frames_sent{0}, frames_replaced{0};
    std::atomic<std::uint64_t> dropped_slow{0}, closed_credential{0}, stops{0}, bad_messages{0};
  };
  Atomics& stats() noexcept { return stats_; }

 private:
  void run() noexcept;
  void publish(std::string_view event) noexcept;

  const HubOptions options_;
  const kernel::Authenticator& auth_;
  kernel::Api& api_;
  const BuildFrame build_;
  Atomics stats_;
  SlotTable slots_;  // upgrades admitted and connections open

  mutable std::mutex clients_mutex_;
  std::set<std::shared_ptr<Connection>> clients_;  // the only strong references while open
  bool stopped_ = false;                           // under clients_mutex_

  std::mutex wake_mutex_;  // events_, stopping_; held only to set or take them
  std::condition_variable wake_;
  unsigned events_ = 0;
  bool stopping_ = false;
  std::uint64_t seq_ = 0;  // the ticker's own
  std::thread ticker_;
};

}  // namespace rcand::services::telemetry
