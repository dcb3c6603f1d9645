// Robot-to-robot messages (seed 004, docs/protocol.md §11) for plugins. The kernel owns every R2R transport, the
// authentication (tokens, Ed25519 signatures) and the validation: a plugin sends and receives through R2rLink and
// never opens a socket. Messages a plugin receives were parsed, validated and authorized first; a bad message never
// reaches a plugin.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include "rcand/sdk/export.hpp"
#include "rcand/sdk/http.hpp"
#include "rcand/sdk/worker.hpp"

namespace rcand::sdk {

// One validated inbound message.
struct R2rMessage {
  std::string type;                      // status | task_request | task_response | command | negotiation | error
  std::string source_id;                 // the sending robot's name
  std::optional<std::string> target_id;  // this robot, or nullopt for a broadcast
  double timestamp = 0.0;                // Unix seconds, as the sender wrote it
  Json payload;                          // checked against the type's payload rules
  std::string principal;                 // who it authenticated as (token principal or signing peer)
  std::string transport;                 // ws | udp | mqtt
};

struct R2rSendResult {
  bool ok = false;
  std::string error;  // why not, when !ok (an invalid payload names the field; R2R not running)
  std::string field;  // JSON pointer of the fault ("/payload/task_id"), when the payload was at fault
};

// A robot's pose in the fleet frame (its dead-reckoned pose plus runtime.r2r.origin).
struct R2rPose {
  double x = 0.0, y = 0.0, heading_deg = 0.0;
};

// A plugin's bid pricing: the task_request payload, the robot's fleet pose (nullopt: unknown) and how many tasks it
// already holds -> estimated seconds to complete, or nullopt to not bid. Any thread; must not block; an exception
// counts as "no bid".
using R2rCostFunction =
    std::function<std::optional<double>(const Json& task_request, const std::optional<R2rPose>& pose, std::size_t queue)>;

class RCAND_INTERFACE R2rLink {
 public:
  using Callback = std::function<void(const R2rMessage&)>;

  virtual ~R2rLink() = default;
  // Any thread, never blocks. Sends a message of `type` to robot `target` (nullopt: every peer), signed and
  // tokened as the robot's config says. The payload is validated first (!ok naming the field when it does not fit).
  virtual R2rSendResult send(std::string_view type, const Json& payload, const std::optional<std::string>& target) = 0;
  // Any thread. `callback` runs on this instance's worker "r2r" (never an I/O thread), one message at a time, for
  // every validated, authorized message of `type`. Throws std::invalid_argument for an unknown type. Returns an id
  // for unsubscribe(); the subscription also ends with the instance.
  virtual std::uint64_t subscribe(std::string_view type, Callback callback) = 0;
  virtual void unsubscribe(std::uint64_t id) noexcept = 0;
  // Any thread. Replaces the robot's bid pricing (default: nav time to the task location plus the queue); an empty
  // function restores the default. The last plugin to set one wins. rcand hands it to the fleet plugin, which runs
  // the auctions (rcand/sdk/interfaces/fleet_auctions.hpp) and calls it on its worker; without that plugin nothing bids.
  virtual void set_cost_function(R2rCostFunction cost) = 0;
};

// Where a plugin gets its R2R link: a service (services.hpp) that rcand's R2R service offers when runtime.r2r.enabled
// (find<R2rLinks>(ctx) is null on a robot without R2R). The link is the plugin's: make it in start(), keep it in
// the instance; its subscriptions end when it is destroyed. PluginContext::r2r(), deprecated, hands out one link
// per instance made the same way.
class RCAND_INTERFACE R2rLinks {
 public:
  static constexpr std::string_view kServiceId = "rcand.r2r_links/1";
  virtual ~R2rLinks() = default;
  // A link whose callbacks run on `worker` (the instance's own, e.g. ctx.worker("r2r")); `who` names the instance
  // in the robot's logs. Null when no link can be made (the host logs why).
  virtual std::unique_ptr<R2rLink> make_link(Worker& worker, std::string_view who) const noexcept = 0;
};

}  // namespace rcand::sdk
