#include "services/r2r/r2r_node.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>

#include "libs/base/bounded_text.hpp"
#include "libs/base/logging.hpp"
#include "libs/r2r_wire/message_signature.hpp"
#include "libs/r2r_wire/payload_schema.hpp"
#include "libs/rcan/ruri.hpp"
#include "services/r2r/refusal_throttle.hpp"
#include "services/r2r/replay_guard.hpp"

namespace rcand::services::r2r {

using namespace rcand::kernel;
using nlohmann::json;

// Named, not anonymous: R2rNode::Impl (external linkage) keeps Routes in its peer table.
namespace node_detail {

// A way back to one sender (the connection its message came on), and whether that transport may carry the token.
struct Route {
  std::function<void(std::string)> send;
  bool may_carry_secrets = false;
  explicit operator bool() const noexcept { return static_cast<bool>(send); }
};

// One message to put on the wire once the node's lock is released, in two spellings: `bytes` with the bearer token
// (when this robot has one) for the transports that may carry it, `open_bytes` without it for every other.
struct Wire {
  std::string bytes;
  std::string open_bytes;
  std::optional<std::string> target;
  Route reply;                                  // preferred route for a direct answer (same connection), may be empty
  std::optional<r2r_wire::MessageType> type{};  // for the message observer; unset for bytes passed on as received
};

}  // namespace node_detail

using node_detail::Route;
using node_detail::Wire;

namespace {

// A change in status is sent at once, but never more often than this (a moving robot changes every tick).
constexpr std::int64_t kMinStatusGapUs = 200'000;

// What the peer table keeps of a peer's status: the ruled fields only, each bounded, so one peer costs at most a few
// KiB whatever it sends (issue 13 #14).
constexpr std::size_t kStatusTextBytes = 64;
constexpr std::size_t kStatusCapabilities = 64;
json r2r_bounded_peer_status(const json& p) {
  json out = json::object();
  for (const char* key : {"battery", "task_progress", "tasks_held"})
    if (const auto it = p.find(key); it != p.end() && (it->is_number() || it->is_null())) out[key] = *it;
  if (const auto it = p.find("estopped"); it != p.end() && it->is_boolean()) out["estopped"] = *it;
  if (const auto it = p.find("state"); it != p.end() && it->is_string())
    out["state"] = bounded_text(it->get_ref<const std::string&>(), kStatusTextBytes);
  if (const auto it = p.find("position"); it != p.end()) {
    if (it->is_object()) {
      json position = json::object();
      for (const char* key : {"x", "y", "heading_deg"})
        if (const auto v = it->find(key); v != it->end() && v->is_number()) position[key] = *v;
      out["position"] = std::move(position);
    } else if (it->is_null()) {
      out["position"] = nullptr;
    }
  }
  if (const auto it = p.find("capabilities"); it != p.end() && it->is_array()) {
    json caps = json::array();
    for (const auto& cap : *it) {
      if (caps.size() >= kStatusCapabilities) break;
      if (cap.is_string()) caps.push_back(bounded_text(cap.get_ref<const std::string&>(), kStatusTextBytes));
    }
    out["capabilities"] = std::move(caps);
  }
  return out;
}

// The sender as the transport knows it: a UDP datagram's IP address ("192.0.2.7" for "192.0.2.7:5000", "::1" for
// "[::1]:5000": its port costs a sender nothing to change); a WebSocket's connection (address and port: each
// connection was authenticated at its upgrade, and their number is capped); empty for MQTT (the broker hides who
// published) and the in-process test network.
std::string r2r_transport_sender(const InboundMessage& message) {
  const std::string& peer = message.peer;
  if (message.transport == "ws") return "ws " + peer;
  if (message.transport != "udp") return {};
  if (!peer.empty() && peer.front() == '[') return "udp " + peer.substr(1, peer.find(']') - 1);
  return "udp " + peer.substr(0, peer.rfind(':'));
}

constexpr std::size_t kSenderNameBytes = 128;  // a sender as the refusal throttle and its summary keep it

}  // namespace

struct R2rNode::Impl {
  explicit Impl(R2rNodeDeps&& d)
      : deps(std::move(d)), auth(deps.authenticator, deps.settings.auth), log(deps.log ? deps.log : spdlog::default_logger()) {
    if (const RuriParse parsed = parse_ruri(deps.identity.ruri); parsed.ruri) own_ruri = parsed.ruri;
    started_s = now_s();
  }

  R2rNodeDeps deps;
  MessageAuthenticator auth;
  std::shared_ptr<spdlog::logger> log;
  std::optional<Ruri> own_ruri;
  // Wall time this node started: a signed message timestamped earlier is refused, so nothing signed before a restart
  // (when the replay memory was lost) can be replayed after it.
  double started_s = 0.0;

  R2rNode::MessageObserver observer;  // set before start(), read without a lock
  mutable std::mutex mutex;           // everything below
  ReplayGuard replays{deps.settings.auth.replay_window_s + deps.settings.auth.future_skew_s};
  std::map<std::uint64_t, std::pair<r2r_wire::MessageType, Subscriber>> subscribers;
  std::uint64_t next_subscriber = 1;
  struct Peer {
    std::int64_t last_seen_ms = 0;
    std::string transport;
    json status;  // null until a status arrives (the ruled fields only, bounded)
    Route reply;
  };
  std::map<std::string, Peer> peers;
  json last_status;  // what was last broadcast
  std::int64_t last_status_us = 0;
  bool status_sent = false;
  NodeCounters counters;
  RefusalThrottle refusals;     // its own locks
  LogRateLimiter error_log{5};  // `error` messages peers send: log lines per sender and second
  std::mutex transports_mutex;  // guards transports and started (never held with `mutex`)
  std::vector<Transport*> transports;
  bool started = false;

  double now_s() const { return static_cast<double>(deps.clock.wall_ms()) / 1000.0; }

  bool is_self(const std::string& id) const {
    if (id == deps.identity.name || id == deps.identity.ruri) return true;
    if (!own_ruri || id.rfind("rcan://", 0) != 0) return false;
    const RuriParse parsed = parse_ruri(id);
    return parsed.ruri && ruri_matches(*parsed.ruri, *own_ruri);
  }

  // The signed (and, with `with_token`, tokened) bytes of a message from this robot.
  std::string build(r2r_wire::MessageType type, json payload, const std::optional<std::string>& target, double timestamp,
                    bool with_token) const {
    json header{
        {"version", std::string(r2r_wire::kProtocolVersion)}, {"timestamp", timestamp}, {"source_id", deps.identity.name}};
    if (target) header["target_id"] = *target;
    json message{{"header", std::move(header)}, {"type", std::string(type_name(type))}, {"payload", std::move(payload)}};
    if (with_token && deps.settings.outbound_token) r2r_wire::add_token(message, *deps.settings.outbound_token);
    if (deps.settings.private_key) r2r_wire::sign_message(message, deps.identity.name, *deps.settings.private_key);
    return message.dump(-1, ' ', false, json::error_handler_t::replace);
  }

  Wire wire(r2r_wire::MessageType type, const json& payload, const std::optional<std::string>& target, Route reply = {}) const {
    const double timestamp = now_s();
    std::string open = build(type, payload, target, timestamp, false);
    std::string full = deps.settings.outbound_token ? build(type, payload, target, timestamp, true) : open;
    return {std::move(full), std::move(open), target, std::move(reply), type};
  }

  // Sends outside `mutex`. A direct answer goes back on the connection it came from when it can; otherwise every
  // transport is tried (broadcasts go to all of them), then the peer's last known route. Each transport gets the
  // spelling it may carry. Returns the names of the transports (or "reply"/"route") that took each message.
  std::vector<std::vector<std::string>> transmit(std::vector<Wire> batch) {
    std::vector<std::vector<std::string>> taken(batch.size());
    for (std::size_t i = 0; i < batch.size(); ++i) {
      Wire& w = batch[i];
      std::vector<std::string>& by = taken[i];
      if (w.reply) {
        w.reply.send(w.reply.may_carry_secrets ? w.bytes : w.open_bytes);
        by.emplace_back("reply");
      } else {
        std::vector<Transport*> targets;
        {
          std::lock_guard lock(transports_mutex);
          if (started) targets = transports;
        }
        for (Transport* transport : targets) {
          if (transport->send_own(w.bytes, w.open_bytes, w.target)) {
            by.emplace_back(transport->name());
            if (w.target) break;
          }
        }
        if (by.empty() && w.target) {
          Route route;
          {
            std::lock_guard lock(mutex);
            if (const auto peer = peers.find(*w.target); peer != peers.end()) route = peer->second.reply;
          }
          if (route) {
            route.send(route.may_carry_secrets ? w.bytes : w.open_bytes);
            by.emplace_back("route");
          }
        }
      }
      if (observer && w.type)
        for (const auto& transport : by) observer(true, *w.type, transport);
      std::lock_guard lock(mutex);
      ++(!by.empty() ? counters.sent : counters.send_failed);
    }
    return taken;
  }

  // The peer table entry for `source`, made room for (the least recently heard goes when the table is full). Under
  // `mutex`.
  Peer& peer_entry_locked(const std::string& source) {
    if (const auto it = peers.find(source); it != peers.end()) return it->second;
    while (!peers.empty() && peers.size() >= std::max<std::size_t>(deps.settings.max_peers, 1)) {
      const auto oldest = std::min_element(
          peers.begin(), peers.end(), [](const auto& a, const auto& b) { return a.second.last_seen_ms < b.second.last_seen_ms; });
      peers.erase(oldest);
    }
    return peers[source];
  }

  void prune_peers_locked(std::int64_t now_ms) {
    const auto expiry_ms = static_cast<std::int64_t>(deps.settings.peer_expiry_s * 1000.0);
    std::erase_if(peers, [&](const auto& entry) { return now_ms - entry.second.last_seen_ms > expiry_ms; });
  }

  // An `error` answering a message from `source` (never to an `error`, never to ourselves).
  // `source` is nullopt when the message was too broken to say who sent it (then only `reply` can carry the answer).
  Wire error_reply(r2r_wire::ErrorCode code, std::string message, const std::optional<json>& ref,
                   const std::optional<std::string>& source, const Route& reply, std::optional<json> extra = std::nullopt) const {
    json payload = r2r_wire::make_error_payload(code, std::move(message), ref);
    if (extra) payload.update(*extra);
    return wire(r2r_wire::MessageType::Error, payload, source, reply);
  }

  // Whether a message for `id` can be passed on: a robot of the fleet (swarm.yaml) or one heard from.
  bool knows(const std::string& id) const {
    if (deps.fleet_member && deps.fleet_member(id)) return true;
    std::lock_guard lock(mutex);
    return peers.contains(id);
  }

  // `source` heard from now, over `transport`; `reply` (when set) becomes the way back to it. Under `mutex`.
  Peer& note_peer_locked(const std::string& source, const std::string& transport, const Route& reply) {
    Peer& peer = peer_entry_locked(source);
    peer.last_seen_ms = deps.clock.wall_ms();
    peer.transport = transport;
    if (reply) peer.reply = reply;
    return peer;
  }

  // Raw bytes to `target` on the first transport that takes them (an answer routed through a relaying robot).
  void send_on_transports(const std::string& bytes, const std::string& target) {
    std::vector<Transport*> targets;
    {
      std::lock_guard lock(transports_mutex);
      if (started) targets = transports;
    }
    for (Transport* transport : targets)
      if (transport->send(bytes, target)) return;
  }

  // A refused message (docs/protocol.md §11.12): counted, then logged (`line`) and answered with the `error` that
  // `answer` builds, each within the sender's budget (RefusalThrottle). Never answered when it came as a broadcast,
  // when it is itself an `error` (`answerable` false), or when no route leads back. `sender`: its source_id, or
  // the transport's peer when it has none; with the transport-level sender when there is one.
  void refuse(const InboundMessage& message, const std::string& sender, bool answerable, const std::string& line,
              const std::function<Wire()>& answer) {
    {
      std::lock_guard lock(mutex);
      ++counters.rejected;
    }
    answerable = answerable && !message.broadcast;
    // A sender is its name over the transport it came by: nobody exhausts another connection's budget by its name.
    const std::string address = r2r_transport_sender(message);
    const std::string who = bounded_text(sender, kSenderNameBytes) + (address.empty() ? "" : " (" + address + ")");
    const auto verdict = refusals.admit(who, address, answerable, deps.clock.now_us());
    if (verdict.log) log->info("r2r: {}", line);
    if (verdict.answer) transmit({answer()});
  }

  // A message for another robot (docs/protocol.md §11.3): passed on once, as received plus the hop marker, when
  // that robot is of the fleet or has been heard from. The sender's own credentials go with it unchanged (a
  // signature still verifies, the marker being outside what it covers; a token travels only where this robot's own
  // would); the relay adds no authority of its own. Otherwise - a relayed message, an unknown target, no transport
  // reaching it - the sender gets 101 (never for an `error`).
  void relay_or_refuse(const InboundMessage& message, const r2r_wire::Envelope& envelope, const json& clean_ref,
                       const Route& reply) {
    const std::string& target = *envelope.target_id;
    std::string why;
    if (envelope.header_extra.contains(r2r_wire::kRelayMarker)) {
      why = "target robot '" + target + "' is not '" + deps.identity.name +
            "', and the message was relayed already: a relayed message is never relayed again";
    } else if (!knows(target)) {
      why = "unknown target robot '" + target + "': '" + deps.identity.name +
            "' has neither it in its fleet (swarm.yaml) nor heard from it";
    } else {
      json message = envelope.received;
      message["header"][r2r_wire::kRelayMarker] = deps.identity.name;
      std::string full = message.dump(-1, ' ', false, json::error_handler_t::replace);
      message["header"].erase("auth");
      std::string open = message.dump(-1, ' ', false, json::error_handler_t::replace);
      if (full.size() > r2r_wire::kMaxMessageBytes) {
        why = "target robot '" + target + "' is known, but the message is too large to relay with the hop marker";
      } else if (!transmit({Wire{std::move(full), std::move(open), target, {}}}).front().empty()) {
        std::lock_guard lock(mutex);
        ++counters.relayed;
        log->debug("r2r: relayed a {} from '{}' to '{}'", type_name(envelope.type), envelope.source_id, target);
        return;
      } else {
        why = "target robot '" + target + "' is known, but no transport reaches it now";
      }
    }
    refuse(message, envelope.source_id, envelope.type != r2r_wire::MessageType::Error,
           std::string(type_name(envelope.type)) + " from '" + envelope.source_id + "' not relayed: " + why,
           [&] { return error_reply(r2r_wire::ErrorCode::UnknownTarget, why, clean_ref, envelope.source_id, reply); });
  }

  // The way back to the sender of a relayed message that came without one (MQTT): through the robot that relayed it,
  // which passes the answer on like any message for a robot it knows. Only for a relay this robot knows itself.
  static Route via_relay(const std::shared_ptr<Impl>& self, const r2r_wire::Envelope& envelope) {
    const auto marker = envelope.header_extra.find(r2r_wire::kRelayMarker);
    if (marker == envelope.header_extra.end() || !marker->is_string()) return {};
    const std::string relay = marker->get<std::string>();
    if (relay.empty() || self->is_self(relay) || !self->knows(relay)) return {};
    return Route{[weak = std::weak_ptr<Impl>(self), relay](std::string bytes) {
                   if (const auto s = weak.lock()) s->send_on_transports(bytes, relay);
                 },
                 false};
  }

  json status_payload_locked(const LocalStatus& local) const {
    json position;
    if (local.pose) {
      const sdk::Pose2d fleet = sdk::compose(deps.settings.origin, *local.pose);
      position = {{"x", fleet.x_m}, {"y", fleet.y_m}, {"heading_deg", fleet.heading_deg}};
    }
    json payload{{"battery", local.battery ? json(*local.battery) : json()},
                 {"position", position},
                 {"task_progress", local.task_progress ? json(*local.task_progress) : json()},
                 {"state", local.state},
                 {"estopped", local.estopped},
                 {"capabilities", deps.identity.capabilities}};
    if (local.tasks_held) payload["tasks_held"] = *local.tasks_held;  // rcand extension: the fleet plugin's queue
    return payload;
  }

  LocalStatus local_status() const { return deps.status_source ? deps.status_source() : LocalStatus{}; }

  // What this robot leaves on its status topic when it goes away (MQTT's last will, and a clean stop): its last
  // status in state "offline", signed now when signing is on.
  std::string offline_status() const {
    json payload;
    {
      std::lock_guard lock(mutex);
      payload = status_sent ? last_status : status_payload_locked(LocalStatus{});
    }
    payload["state"] = "offline";
    payload["task_progress"] = nullptr;
    return wire(r2r_wire::MessageType::Status, payload, std::nullopt).open_bytes;
  }

  // This robot's status now, sent at once whatever the interval (a fleet e-stop's latch: the fleet sees it now).
  void publish_status_now() {
    const LocalStatus local = local_status();
    std::vector<Wire> out;
    {
      std::lock_guard lock(mutex);
      json status = status_payload_locked(local);
      out.push_back(wire(r2r_wire::MessageType::Status, status, std::nullopt));
      last_status = std::move(status);
      last_status_us = deps.clock.now_us();
      status_sent = true;
    }
    transmit(std::move(out));
  }

  // The fleet e-stop (docs/protocol.md §11.15): POST /api/stop's latch as the sender, on this (transport) thread, then
  // the latched status at once (through deps.after_stop). The latch's reason names the sender and its reason.
  void fleet_estop(const Principal& principal, const r2r_wire::Envelope& envelope, const std::string& transport) {
    const auto it = envelope.payload.find("reason");
    const std::string reason = it != envelope.payload.end() && it->is_string() ? it->get<std::string>() : std::string();
    const std::string text = "fleet e-stop from '" + envelope.source_id + "'" + (reason.empty() ? "" : ": " + reason);
    log->warn("r2r: {} (via {})", bounded_text(text, 300), transport);
    deps.stop_executor(principal,
                       json{{"reason", bounded_text(text, 200)}, {"from", "r2r " + bounded_text(envelope.source_id, 60)}});
    if (deps.after_stop) deps.after_stop([this] { publish_status_now(); });
    else publish_status_now();
  }

  // receive()'s steps, in order (defined below, beside the helpers they use).
  struct Incoming {
    const InboundMessage& message;
    r2r_wire::Envelope envelope;
    Route reply;
    json clean_ref;  // the `ref` of any answer: the header, minus credentials
    bool estop;      // a fleet e-stop
    double now;
  };
  // A message that is no R2R message: refused with the fault and, where one was found, its field.
  void refuse_malformed(const InboundMessage& message, const r2r_wire::R2rError& bad, const Route& reply);
  void refuse_unauthorized(const Incoming& in, const std::string& line, const std::string& why);
  // Who sent it (token, signature or transport principal), or nullopt once refused.
  std::optional<Principal> authenticate(const Incoming& in);
  // False for a signed message that may be a replay: signed before this robot started (refused) or seen (dropped).
  bool first_time(const Incoming& in, const Principal& principal);
  // Counts it and notes its sender (and a status); the subscribers of its type. `is_command` for a command.
  std::vector<Subscriber> record(const Incoming& in, bool& is_command);
  // The fleet e-stop, or the command through the kernel; false when this robot takes no commands (refused).
  static bool run_command(const std::shared_ptr<Impl>& self, const Incoming& in, const Principal& principal);
  void notify(const std::vector<Subscriber>& to_notify, Incoming&& in, const Principal& principal);
};

namespace {
// A status on its sender's own status topic (MQTT r2r/status/<name>, docs/protocol.md §11.13) may be a retained copy
// set before this robot started: a status is no action, so that is no replay to refuse.
bool r2r_status_on_own_topic(const InboundMessage& message, const r2r_wire::Envelope& envelope) {
  return message.status_topic && envelope.type == r2r_wire::MessageType::Status &&
         message.peer.ends_with("/status/" + envelope.source_id);
}
// The `offline` status left there (the last will, or published at a clean stop) was signed when it was set, possibly
// long ago: its signature is checked as of its own timestamp, and all it can ever do is mark that robot offline.
bool r2r_offline_left_behind(const InboundMessage& message, const r2r_wire::Envelope& envelope) {
  const auto state = envelope.payload.find("state");
  return r2r_status_on_own_topic(message, envelope) && state != envelope.payload.end() && *state == "offline";
}
}  // namespace

// receive()'s steps.

void R2rNode::Impl::refuse_malformed(const InboundMessage& message, const r2r_wire::R2rError& bad, const Route& reply) {
  const bool answerable = bad.type != "error" && !(bad.source_id && is_self(*bad.source_id)) && (bad.source_id || reply);
  refuse(message, bad.source_id.value_or(message.transport + " " + message.peer), answerable,
         "refused a message from " + message.peer + " via " + message.transport + ": " + bad.message +
             (bad.field.empty() ? "" : " at " + bad.field),
         [&] {
           json extra = json::object();
           if (!bad.field.empty()) extra["field"] = bad.field;  // rcand extension: where the fault is
           return error_reply(bad.code, bad.message, bad.ref, bad.source_id, reply, extra);
         });
}

void R2rNode::Impl::refuse_unauthorized(const Incoming& in, const std::string& line, const std::string& why) {
  const std::string& source = in.envelope.source_id;
  refuse(in.message, source, in.envelope.type != r2r_wire::MessageType::Error, line,
         [&] { return error_reply(r2r_wire::ErrorCode::Unauthorized, why, in.clean_ref, source, in.reply); });
}

std::optional<Principal> R2rNode::Impl::authenticate(const Incoming& in) {
  const r2r_wire::Envelope& envelope = in.envelope;
  // A fleet e-stop needs what POST /api/stop needs (scope status); any other command, control.
  auto who = auth.authorize(envelope, envelope.received, in.message.principal,
                            in.estop ? sdk::Scope::Status : required_scope(envelope.type),
                            r2r_offline_left_behind(in.message, envelope) ? envelope.timestamp : in.now);
  // Through a broker or a broadcast address no bearer token authenticates a sender: there a stop must be signed.
  if (in.estop && !transport_may_carry_secrets(in.message.transport) && std::holds_alternative<Principal>(who) &&
      std::get<Principal>(who).via != "signature")
    who = AuthFailure{"a fleet e-stop via " + in.message.transport + " must be signed (header.signature)"};
  if (const auto* failure = std::get_if<AuthFailure>(&who)) {
    refuse_unauthorized(in,
                        "unauthorized " + std::string(in.estop ? "fleet e-stop" : type_name(envelope.type)) + " from '" +
                            envelope.source_id + "' via " + in.message.transport + ": " + failure->message,
                        failure->message);
    return std::nullopt;
  }
  return std::move(std::get<Principal>(who));
}

bool R2rNode::Impl::first_time(const Incoming& in, const Principal& principal) {
  if (principal.via != "signature") return true;
  const r2r_wire::Envelope& envelope = in.envelope;
  // Signed before this robot started: its replay memory cannot know whether it was handled before a restart, so it
  // is refused (103) - nothing signed before a restart is replayable after it.
  if (envelope.timestamp < started_s && !r2r_status_on_own_topic(in.message, envelope)) {
    const std::string why =
        "signed message timestamped before this robot started (" + json(started_s).dump() + "): refused as a possible replay";
    refuse_unauthorized(in,
                        "refused a signed " + std::string(type_name(envelope.type)) + " from '" + envelope.source_id + "' via " +
                            in.message.transport + ": " + why,
                        why);
    return false;
  }
  // A copy of a signed message already handled: a replay, or the same broadcast over another transport. Keyed on
  // the canonical signed message, so no other spelling of it counts as new. Dropped without an answer (the
  // original was answered); a debug line only, as the same broadcast on two transports is no fault.
  const std::string key = replay_key(envelope.received);
  std::lock_guard lock(mutex);
  if (replays.first_time(key, in.now)) return true;
  ++counters.rejected;
  log->debug("r2r: dropped a repeated signed {} from '{}'", type_name(envelope.type), envelope.source_id);
  return false;
}

std::vector<Subscriber> R2rNode::Impl::record(const Incoming& in, bool& is_command) {
  const r2r_wire::Envelope& envelope = in.envelope;
  const std::string& source = envelope.source_id;
  std::vector<Subscriber> to_notify;
  std::lock_guard lock(mutex);
  ++counters.accepted;
  Peer& peer = note_peer_locked(source, in.message.transport, in.reply);
  const json& p = envelope.payload;
  // Task requests, negotiations and task responses are the fleet plugin's (it subscribes): the auction runs there.
  switch (envelope.type) {
    case r2r_wire::MessageType::Status: peer.status = r2r_bounded_peer_status(p); break;
    case r2r_wire::MessageType::Error: {
      // A peer's own text: logged within its budget (the formatter escapes and bounds it, as every message).
      const int code = p["code"].get<int>();
      if (const auto verdict = error_log.admit(bounded_text(source, kSenderNameBytes)); verdict.log)
        log->info("r2r: error {} ({}) from '{}': {}{}", code, r2r_wire::error_code_name(code), source,
                  p["message"].get<std::string>(),
                  verdict.suppressed ? " (" + std::to_string(verdict.suppressed) + " earlier ones not logged)" : "");
      break;
    }
    case r2r_wire::MessageType::Command: is_command = true; break;
    case r2r_wire::MessageType::TaskRequest:
    case r2r_wire::MessageType::TaskResponse:
    case r2r_wire::MessageType::Negotiation: break;
  }
  for (const auto& [id, entry] : subscribers)
    if (entry.first == envelope.type) to_notify.push_back(entry.second);
  return to_notify;
}

bool R2rNode::Impl::run_command(const std::shared_ptr<Impl>& self, const Incoming& in, const Principal& principal) {
  if (in.estop && self->deps.stop_executor) {
    self->fleet_estop(principal, in.envelope, in.message.transport);
    return true;
  }
  const std::string& source = in.envelope.source_id;
  if (!self->deps.command_executor) {
    self->refuse_unauthorized(in, "command from '" + source + "' refused: this robot does not accept R2R commands",
                              "this robot does not accept R2R commands");
    return false;
  }
  // Refused (405, 423, ...): the sender learns why, unless the command came as a broadcast (§11.12).
  auto on_refusal = [weak = std::weak_ptr<Impl>(self), clean_ref = in.clean_ref, source, reply = in.reply,
                     broadcast = in.message.broadcast](int status, json body) {
    const auto s = weak.lock();
    if (!s || (status >= 200 && status < 300) || broadcast) return;
    const std::string why = body.is_object() && body.contains("error") && body["error"].is_string()
                                ? body["error"].get<std::string>()
                                : "command failed";
    const r2r_wire::ErrorCode code = status == 423                    ? r2r_wire::ErrorCode::EstopActive
                                     : status == 401 || status == 403 ? r2r_wire::ErrorCode::Unauthorized
                                                                      : r2r_wire::ErrorCode::InvalidFormat;
    json extra{{"http_status", status}};  // rcand extension: the HTTP-equivalent answer
    if (body.is_object() && body.contains("code")) extra["http_code"] = body["code"];
    s->transmit({s->error_reply(code, why, clean_ref, source, reply, extra)});
  };
  self->deps.command_executor(principal, in.envelope.payload, std::move(on_refusal));
  return true;
}

void R2rNode::Impl::notify(const std::vector<Subscriber>& to_notify, Incoming&& in, const Principal& principal) {
  if (to_notify.empty()) return;
  const ReceivedMessage received{std::move(in.envelope), principal.name, in.message.transport};
  for (const Subscriber& callback : to_notify) {
    try {
      callback(received);
    } catch (const std::exception& e) {
      log->warn("r2r: a subscriber threw: {}", e.what());
    } catch (...) {
      log->warn("r2r: a subscriber threw");
    }
  }
}

R2rNode::R2rNode(R2rNodeDeps deps) : identity_(deps.identity), impl_(std::make_shared<Impl>(std::move(deps))) {
  for (Transport* transport : impl_->deps.transports) add_transport(transport);
}

R2rNode::~R2rNode() { stop(); }

void R2rNode::add_transport(Transport* transport) {
  if (transport == nullptr) return;
  std::lock_guard lock(impl_->transports_mutex);
  if (std::find(impl_->transports.begin(), impl_->transports.end(), transport) == impl_->transports.end())
    impl_->transports.push_back(transport);
}

void R2rNode::start() {
  std::vector<Transport*> transports;
  {
    std::lock_guard lock(impl_->transports_mutex);
    transports = impl_->transports;
    impl_->started = true;
  }
  // stop() (also run by the destructor) stops every transport, so no delivery outlives the node.
  for (Transport* transport : transports) {
    transport->set_offline_status([weak = std::weak_ptr<Impl>(impl_)] {
      const auto self = weak.lock();
      return self ? self->offline_status() : std::string();
    });
    transport->start([this](InboundMessage message) { receive(std::move(message)); });
  }
}

void R2rNode::stop() noexcept {
  std::vector<Transport*> transports;
  {
    std::lock_guard lock(impl_->transports_mutex);
    if (!impl_->started) return;
    impl_->started = false;
    transports = impl_->transports;
  }
  for (Transport* transport : transports) transport->stop();
}

void R2rNode::receive(InboundMessage message) {
  Impl& s = *impl_;
  Route reply{message.reply, transport_may_carry_secrets(message.transport) && message.trusted_with_secrets};
  {
    std::lock_guard lock(s.mutex);
    ++s.counters.received;
  }
  auto parsed = r2r_wire::parse_envelope(message.bytes);
  if (const auto* bad = std::get_if<r2r_wire::R2rError>(&parsed)) return s.refuse_malformed(message, *bad, reply);
  r2r_wire::Envelope envelope = std::move(std::get<r2r_wire::Envelope>(parsed));
  if (s.is_self(envelope.source_id)) return;  // our own broadcast, echoed back by a transport
  if (!reply) reply = Impl::via_relay(impl_, envelope);
  json clean_ref = envelope.header_extra;
  clean_ref.erase("auth");
  clean_ref.erase("signature");
  const bool estop = is_fleet_estop(envelope.type, envelope.payload);
  Impl::Incoming in{message, std::move(envelope), std::move(reply), std::move(clean_ref), estop, s.now_s()};

  const auto principal = s.authenticate(in);
  if (!principal || !s.first_time(in, *principal)) return;
  if (in.envelope.target_id && !s.is_self(*in.envelope.target_id)) {
    {
      std::lock_guard lock(s.mutex);
      s.note_peer_locked(in.envelope.source_id, message.transport, in.reply);  // so the target's answer finds its way back
    }
    s.relay_or_refuse(message, in.envelope, in.clean_ref, in.reply);
    return;
  }
  bool command = false;
  const auto to_notify = s.record(in, command);
  if (s.observer) s.observer(false, in.envelope.type, message.transport);
  if (command && !Impl::run_command(impl_, in, *principal)) return;
  s.notify(to_notify, std::move(in), *principal);
}

void R2rNode::tick() {
  Impl& s = *impl_;
  const LocalStatus local = s.local_status();
  const std::int64_t now_us = s.deps.clock.now_us();
  std::vector<Wire> out;
  {
    std::lock_guard lock(s.mutex);
    json status = s.status_payload_locked(local);
    const std::int64_t since = now_us - s.last_status_us;
    const bool due = !s.status_sent || since >= std::chrono::microseconds(s.deps.settings.status_interval).count();
    const bool changed = s.status_sent && status != s.last_status && since >= kMinStatusGapUs;
    if (due || changed) {
      out.push_back(s.wire(r2r_wire::MessageType::Status, status, std::nullopt));
      s.last_status = std::move(status);
      s.last_status_us = now_us;
      s.status_sent = true;
    }
    s.prune_peers_locked(s.deps.clock.wall_ms());
  }
  s.transmit(std::move(out));
  if (const auto summary = s.refusals.summary(now_us)) s.log->info("{}", *summary);
}

std::variant<std::string, r2r_wire::R2rError> R2rNode::send(r2r_wire::MessageType type, json payload,
                                                            const std::optional<std::string>& target) {
  auto outcome = send_message(type, std::move(payload), target);
  if (auto* error = std::get_if<r2r_wire::R2rError>(&outcome)) return std::move(*error);
  return std::move(std::get<SendOutcome>(outcome).bytes);
}

std::variant<SendOutcome, r2r_wire::R2rError> R2rNode::send_message(r2r_wire::MessageType type, json payload,
                                                                    const std::optional<std::string>& target) {
  auto invalid = [](std::string field, std::string message) {
    r2r_wire::R2rError error;
    error.field = std::move(field);
    error.message = std::move(message);
    return error;
  };
  if (!payload.is_object()) return invalid("/payload", "payload must be an object");
  if (auto fault = check_payload(type, payload)) return invalid(fault->field, fault->message);
  if (target && target->empty()) return invalid("/header/target_id", "target_id must not be empty");
  Wire w = impl_->wire(type, payload, target);
  const std::size_t size = std::max(w.bytes.size(), w.open_bytes.size());
  if (size > r2r_wire::kMaxMessageBytes)
    return invalid("", "message is " + std::to_string(size) + " bytes, more than the " +
                           std::to_string(r2r_wire::kMaxMessageBytes) + " allowed");
  SendOutcome outcome;
  outcome.bytes = w.open_bytes;
  outcome.queued_on = std::move(impl_->transmit({std::move(w)}).front());
  return outcome;
}

void R2rNode::observe_messages(MessageObserver observer) { impl_->observer = std::move(observer); }

std::uint64_t R2rNode::subscribe(r2r_wire::MessageType type, Subscriber callback) {
  std::lock_guard lock(impl_->mutex);
  const std::uint64_t id = impl_->next_subscriber++;
  impl_->subscribers.emplace(id, std::make_pair(type, std::move(callback)));
  return id;
}

void R2rNode::unsubscribe(std::uint64_t id) {
  std::lock_guard lock(impl_->mutex);
  impl_->subscribers.erase(id);
}

json R2rNode::peers() const {
  std::lock_guard lock(impl_->mutex);
  json list = json::array();
  for (const auto& [name, peer] : impl_->peers)
    list.push_back({{"name", name}, {"last_seen_ms", peer.last_seen_ms}, {"transport", peer.transport}, {"status", peer.status}});
  return {{"peers", std::move(list)}};
}

json R2rNode::status_payload() const {
  const LocalStatus local = impl_->local_status();
  std::lock_guard lock(impl_->mutex);
  return impl_->status_payload_locked(local);
}

void R2rNode::replace_peers(std::vector<r2r_wire::PeerKey> peers) { impl_->auth.replace_peers(std::move(peers)); }

NodeCounters R2rNode::counters() const {
  std::lock_guard lock(impl_->mutex);
  return impl_->counters;
}

}  // namespace rcand::services::r2r
