// One robot's R2R endpoint (seed 004, docs/protocol.md §11). Parses every inbound message, authenticates it, checks its
// target, dispatches it per type and answers with `error` messages as the rulings say (never to a message that came as
// a broadcast; refusals logged and answered within each sender's budget, RefusalThrottle, summed up from tick());
// runs commands through the
// action path; sends `status` periodically and on change; keeps a peer table; hands validated messages to
// subscribers (plugins: the fleet plugin runs the auctions, §11.7-§11.9, on what it receives and sends here). No
// thread of its own: transports call receive() on their threads, the owner calls tick() periodically (every ~50-100
// ms) on any thread. Every public method is thread-safe and never blocks on I/O; messages are sent outside the
// node's lock, so a transport may deliver synchronously.
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
#include "libs/r2r_wire/envelope.hpp"
#include "rcand/sdk/clock.hpp"
#include "rcand/sdk/interfaces/pose_source.hpp"
#include "services/r2r/message_auth.hpp"
#include "services/r2r/r2r_settings.hpp"
#include "services/r2r/transport.hpp"

namespace rcand::services::r2r {

struct NodeIdentity {
  std::string name;                       // metadata.robot_name: source_id of everything this node sends
  std::string ruri;                       // accepted as an alias of `name` in target_id
  std::vector<std::string> capabilities;  // the registry's names (what this robot may bid with)
};

// What the robot reports in `status` (docs/protocol.md §11.6). pose is in the robot's own dead-reckoned frame (nav's
// pose); the node places it in the fleet frame by runtime.r2r.origin (sdk::compose).
struct LocalStatus {
  std::optional<double> battery;        // 0..100
  std::optional<sdk::Pose2d> pose;      // nullopt: unknown (nav not running)
  std::optional<double> task_progress;  // 0..1; nullopt: null
  std::string state = "idle";           // idle | running | error | estop
  bool estopped = false;
  std::optional<std::size_t> tasks_held;  // the rcand extension `tasks_held` (the fleet plugin's); nullopt: left out
};
// Any thread; must not block (the R2R service reads the status snapshot, the e-stop latch and the fleet plugin).
using StatusSource = std::function<LocalStatus()>;

// Runs a `command` payload exactly as POST /api/action with that body, as `principal` (scope check, the 423 e-stop
// pre-check, the audit entry). `done` is called once, from any thread, with the HTTP status and JSON body.
using CommandDone = std::function<void(int http_status, nlohmann::json body)>;
using CommandExecutor = std::function<void(const kernel::Principal& principal, nlohmann::json body, CommandDone done)>;
// The fleet e-stop (docs/protocol.md §11.15): a `command` whose payload is {"type":"estop","reason"?} latches the robot
// exactly as POST /api/stop with `body` ({"reason","from"}) as `principal` - same audit entry, same latch - on the
// calling (transport) thread: never behind a worker queue. Returns once latched. There is no R2R way to clear.
using StopExecutor = std::function<void(const kernel::Principal& principal, nlohmann::json body)>;

// A validated inbound message as subscribers see it.
struct ReceivedMessage {
  r2r_wire::Envelope envelope;
  std::string principal;  // who it authenticated as
  std::string transport;  // "ws" | "udp" | "mqtt" | "local"
};
using Subscriber = std::function<void(const ReceivedMessage&)>;

struct R2rNodeDeps {
  NodeIdentity identity;
  const sdk::Clock& clock;
  const kernel::Authenticator& authenticator;  // the robot's HTTP authenticator: header.auth.token is checked against it
  R2rSettings settings;
  StatusSource status_source;          // may be empty: status says unknown everywhere
  CommandExecutor command_executor;    // may be empty: every command is refused (code 103, "commands disabled")
  std::vector<Transport*> transports;  // not owned; outlive the node. Also add_transport() later.
  // Whether `id` names another robot of this robot's fleet (swarm.yaml): a message for it is relayed (§11.3), as is
  // one for a robot in the peer table. May be empty (only heard peers are known). Any thread; must not block.
  std::function<bool(const std::string& id)> fleet_member;
  std::shared_ptr<spdlog::logger> log;  // null: spdlog's default logger
  StopExecutor stop_executor;           // may be empty: a fleet e-stop is refused (code 103, "commands disabled")
  // Runs what follows a fleet e-stop (the latched status: a signature and a send) off the receiving thread, so on
  // saturated cores every robot's stop goes first. Must run it only while the node lives. Empty: inline.
  std::function<void(std::function<void()>)> after_stop;
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
  std::uint64_t relayed = 0;  // messages for another robot of the fleet passed on (docs/protocol.md §11.3)
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
  // Periodic work against the clock: status every status_interval and on change, peer expiry, the summary of
  // refusals held back.
  void tick();

  // Sends a message of `type` with `payload` to `target` (nullopt: broadcast) on every transport that accepts it,
  // signed/tokened per settings. Returns the bytes sent, or an R2rError (code 100) when the payload is invalid for the
  // type. True delivery is not confirmed (UDP, MQTT QoS 0).
  std::variant<std::string, r2r_wire::R2rError> send(r2r_wire::MessageType type, nlohmann::json payload,
                                                     const std::optional<std::string>& target);
  // The same, saying which transports took it.
  std::variant<SendOutcome, r2r_wire::R2rError> send_message(r2r_wire::MessageType type, nlohmann::json payload,
                                                             const std::optional<std::string>& target);

  // Subscribers get every validated, authorized message of `type` (any transport). The callback runs on the
  // thread that delivered the message: wrap it to post elsewhere (the plugin link posts to the plugin's worker).
  std::uint64_t subscribe(r2r_wire::MessageType type, Subscriber callback);
  // Told of each message accepted from a transport (sent: false) and each one a transport took (sent: true; "reply"
  // and "route" name the way back to a peer). Any thread; must not block. Before start() only (metrics).
  using MessageObserver = std::function<void(bool sent, r2r_wire::MessageType type, const std::string& transport)>;
  void observe_messages(MessageObserver observer);
  void unsubscribe(std::uint64_t id);

  // {"peers":[{"name","last_seen_ms","transport","status":{...}}]}: the last status (its ruled fields, bounded) of
  // every robot heard from within runtime.r2r.peer_expiry_s, at most runtime.r2r.max_peers of them.
  nlohmann::json peers() const;
  // The status payload this robot would send now.
  nlohmann::json status_payload() const;
  NodeCounters counters() const;
  const NodeIdentity& identity() const noexcept { return identity_; }
  // The peers whose signatures are accepted from now on, all at once (a SIGHUP reload of runtime.r2r.peers_file).
  void replace_peers(std::vector<r2r_wire::PeerKey> peers);

 private:
  struct Impl;
  NodeIdentity identity_;
  std::shared_ptr<Impl> impl_;  // shared with pending command completions, which may outlive the node
};

}  // namespace rcand::services::r2r
