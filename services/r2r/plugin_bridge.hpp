// Plugins' side of R2R: one bridge per kernel, one sdk::R2rLink per plugin instance. The bridge exists before any
// plugin starts, so a plugin may subscribe in its constructor or start(); the node is attached once R2R runs (after
// the plugins), and detached first at shutdown. Callbacks are posted to the instance's worker, never run on a
// transport thread, and only ever see messages the node validated and authorized. A price set with
// R2rLink::set_cost_function is handed on to the fleet plugin, which runs the auctions (sdk::FleetAuctions).
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "rcand/sdk/interfaces/fleet_auctions.hpp"
#include "rcand/sdk/r2r.hpp"
#include "rcand/sdk/worker.hpp"
#include "services/r2r/r2r_node.hpp"

namespace rcand::services::r2r {

class PluginBridge {
 public:
  using FleetLookup = std::function<const sdk::FleetAuctions*()>;
  // `fleet`: where bid prices go (sdk::find<sdk::FleetAuctions> over the plugins' services); empty: nowhere.
  explicit PluginBridge(FleetLookup fleet = {}) : fleet_(std::move(fleet)) {}
  ~PluginBridge();  // detach()
  PluginBridge(const PluginBridge&) = delete;
  PluginBridge& operator=(const PluginBridge&) = delete;

  // Starts relaying `node`'s messages to plugin subscribers.
  void attach(R2rNode& node);
  // Stops relaying; sends fail with "R2R is not running" afterwards. Idempotent. Call before the node is destroyed.
  void detach() noexcept;

  // The link for one plugin instance: its callbacks run on `worker`; `owner` names it in logs. The link must be
  // destroyed before the bridge (the kernel destroys plugin instances first).
  std::unique_ptr<sdk::R2rLink> make_link(sdk::Worker& worker, std::string owner);
  // Hands the price a plugin set (or none) to the fleet plugin, unless that one has it already. Also done at every
  // set_cost_function and when the link that set it goes; the R2R service calls it whenever plugin instances start
  // or are reloaded (Service::capabilities_changed), for a price set before the fleet plugin offered its service.
  // `again`: even to the object that has it (a reloaded fleet plugin may sit where the old one did). Any thread.
  void sync_cost(bool again = false) noexcept;

 private:
  class Link;
  struct Subscription {
    r2r_wire::MessageType type;
    sdk::Worker* worker;
    sdk::R2rLink::Callback callback;
    std::shared_ptr<bool> live;  // false once unsubscribed: queued deliveries then do nothing
  };
  void deliver(const ReceivedMessage& message);
  sdk::R2rSendResult send(std::string_view type, const sdk::Json& payload, const std::optional<std::string>& target);
  std::uint64_t subscribe(const Link* owner, std::string_view type, sdk::R2rLink::Callback callback, sdk::Worker& worker);
  void unsubscribe(std::uint64_t id) noexcept;
  void set_cost(const Link* owner, sdk::R2rCostFunction cost);
  void forget(const Link* owner) noexcept;

  const FleetLookup fleet_;
  std::mutex sync_mutex_;  // serializes sync_cost(); taken before mutex_, never inside it
  const sdk::FleetAuctions* synced_fleet_ = nullptr;
  std::uint64_t synced_generation_ = 0;

  mutable std::mutex mutex_;
  R2rNode* node_ = nullptr;
  std::vector<std::uint64_t> node_subscriptions_;
  std::map<std::uint64_t, std::pair<const Link*, Subscription>> subscriptions_;
  std::uint64_t next_id_ = 1;
  const Link* cost_owner_ = nullptr;
  sdk::R2rCostFunction cost_;
  std::uint64_t cost_generation_ = 0;  // grows with every change of cost_
};

}  // namespace rcand::services::r2r
