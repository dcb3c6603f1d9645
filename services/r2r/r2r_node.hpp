// One robot's R2R endpoint (seed 004, docs/protocol.md §11). Parses every inbound message, authenticates it, checks its
// target, dispatches it per type and answers with `error` messages as the rulings say; sends `status` periodically and
// on change; runs auctions (as requester) and bids on others' (as bidder); keeps a peer table; hands validated
// messages to subscribers (plugins). No thread of its own: transports call receive() on their threads, the owner
// calls tick() periodically (every ~50-100 ms) on any thread. Every public method is thread-safe and never blocks
// on I/O; messages are sent outside the node's lock, so a transport may deliver synchronously.
#pragma once

#include <nlohmann/json.hpp>

#include <atomic>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <spdlog/logger.h>

#include "kernel/auth/authenticator.hpp"
#include "rcand/sdk/clock.hpp"
#include "services/r2r/auction.hpp"
#include "services/r2r/cost_function.hpp"
#include "services/r2r/envelope.hpp"
#include "services/r2r/message_auth.hpp"
#include "services/r2r/r2r_settings.hpp"
#include "services/r2r/transport.hpp"

namespace rcand::kernel::r2r {

struct NodeIdentity {
  std::string name;                       // metadata.robot_name: source_id of everything this node sends
  std::string ruri;                       // accepted as an alias of `name` in target_id
  std::vector<std::string> capabilities;  // the registry's names (what this robot may bid with)
};

// What the robot reports in `status` (docs/protocol.md §11). pose is in the robot's own dead-reckoned frame (nav's pose); the
// node adds runtime.r2r.origin.
struct LocalStatus {
  std::optional<double> battery;        // 0..100
  std::optional<FleetPose> pose;        // nullopt: unknown (nav not running)
  std::optional<double> task_progress;  // 0..1; nullopt: the node reports its own (held tasks) or null
  std::string state = "idle";           // idle | running | error | estop
  bool estopped = false;
};
// Any thread; must not block (the kernel reads nav's status and the e-stop latch).
using StatusSource = std::function<LocalStatus()>;

// Runs a `command` payload exactly as POST /api/action with that body, as `principal` (scope check, the 423 e-stop
// pre-check, the audit entry). `done` is called once, from any thread, with the HTTP status and JSON body.
using CommandDone = std::function<void(int http_status, nlohmann::json body)>;
using CommandExecutor = std::function<void(const Principal& principal, nlohmann::json body, CommandDone done)>;

// A validated inbound message as subscribers see it.
struct ReceivedMessage {
  Envelope envelope;
  std::string principal;  // who it authenticated as
  std::string transport;  // "ws" | "udp" | "mqtt" | "local"
};
using Subscriber = std::function<void(const ReceivedMessage&)>;

struct R2rNodeDeps {
  NodeIdentity identity;
  const sdk::Clock& clock;
  const Authenticator& authenticator;  // the robot's HTTP authenticator: header.auth.token is checked against it
  R2rSettings settings;
  StatusSource status_source;           // may be empty: status says unknown everywhere
  CommandExecutor command_executor;     // may be empty: every command is refused (code 103, "commands disabled")
  CostFunction cost_function;           // empty: nav_time_cost(physics below)
  DrivePhysics physics;                 // for the default cost function
  std::vector<Transport*> transports;   // not owned; outlive the node. Also add_transport() later.
  std::shared_ptr<spdlog::logger> log;  // null: spdlog's default logger
};

// What send_message() did: the message as sent without any bearer token (the spelling safe to show), and the
// transports that accepted it for delivery (queued: true delivery is not confirmed - UDP, MQTT QoS 0, a WebSocket
// write queue). Empty when no transport could take it (for example an unknown target).
struct SendOutcome {
  std::string bytes;
  std::vector<std::string> queued_on;  // "ws" | "udp" | "mqtt" | "route" (the peer's last connection)
};

struct NodeCounters {
  std::uint64_t received = 0, accepted = 0, rejected = 0, sent = 0, send_failed = 0;
};

class R2rNode {
 public:
  explicit R2rNode(R2rNodeDeps deps);
  ~R2rNode();
  R2rNode(const R2rNode&) = delete;
  R2rNode& operator=(const R2rNode&) = delete;

  // Starts every transport with this node's receive(). Throws what a transport throws (naming the setting).
  void start();
  // Stops every transport; no receive() runs after it returns. Idempotent.
  void stop() noexcept;
  // Adds a transport before start() (the kernel builds them from config after the node).
  void add_transport(Transport* transport);

  // The Deliver callback: any transport thread, never blocks.
  void receive(InboundMessage message);
  // Periodic work against the clock: status every status_interval and on change, auction deadlines.
  void tick();

  // Sends a message of `type` with `payload` to `target` (nullopt: broadcast) on every transport that accepts it,
  // signed/tokened per settings. Returns the bytes sent, or an R2rError (code 100) when the payload is invalid for the
  // type. True delivery is not confirmed (UDP, MQTT QoS 0).
  std::variant<std::string, R2rError> send(MessageType type, nlohmann::json payload, const std::optional<std::string>& target);
  // The same, saying which transports took it.
  std::variant<SendOutcome, R2rError> send_message(MessageType type, nlohmann::json payload,
                                                   const std::optional<std::string>& target);

  // Opens an auction for `task` (task_request broadcast with bid_deadline = now + bid_window). task_id may be
  // empty: one is generated. Returns the task id, or an R2rError when the task is invalid.
  std::variant<std::string, R2rError> open_auction(TaskSpec task);
  // The auction's state and all bids, or nullopt when this node never opened it.
  std::optional<nlohmann::json> auction_result(const std::string& task_id) const;
  // Tasks this robot holds (won), and releasing one when done.
  nlohmann::json held_tasks() const;
  bool complete_task(const std::string& task_id);

  // Subscribers get every validated, authorized message of `type` (any transport). The callback runs on the
  // thread that delivered the message: wrap it to post elsewhere (the plugin link posts to the plugin's worker).
  std::uint64_t subscribe(MessageType type, Subscriber callback);
  void unsubscribe(std::uint64_t id);
  // Replaces the cost function (a plugin's); empty restores the default.
  void set_cost_function(CostFunction cost);

  // {"peers":[{"name","last_seen_ms","transport","status":{...}}]}: the last status (its ruled fields, bounded) of
  // every robot heard from within runtime.r2r.peer_expiry_s, at most runtime.r2r.max_peers of them.
  nlohmann::json peers() const;
  // The status payload this robot would send now.
  nlohmann::json status_payload() const;
  NodeCounters counters() const;
  const NodeIdentity& identity() const noexcept { return identity_; }

 private:
  struct Impl;
  NodeIdentity identity_;
  std::shared_ptr<Impl> impl_;  // shared with pending command completions, which may outlive the node
};

}  // namespace rcand::kernel::r2r
