#include "services/r2r/plugin_bridge.hpp"

#include <spdlog/spdlog.h>

#include <memory>
#include <stdexcept>

namespace rcand::services::r2r {

constexpr r2r_wire::MessageType kAllTypes[] = {r2r_wire::MessageType::Status,       r2r_wire::MessageType::TaskRequest,
                                               r2r_wire::MessageType::TaskResponse, r2r_wire::MessageType::Command,
                                               r2r_wire::MessageType::Negotiation,  r2r_wire::MessageType::Error};

class PluginBridge::Link final : public sdk::R2rLink {
 public:
  Link(PluginBridge& bridge, sdk::Worker& worker, std::string owner)
      : bridge_(bridge), worker_(worker), owner_(std::move(owner)) {}
  ~Link() override { bridge_.forget(this); }

  sdk::R2rSendResult send(std::string_view type, const sdk::Json& payload, const std::optional<std::string>& target) override {
    return bridge_.send(type, payload, target);
  }
  std::uint64_t subscribe(std::string_view type, Callback callback) override {
    return bridge_.subscribe(this, type, std::move(callback), worker_);
  }
  void unsubscribe(std::uint64_t id) noexcept override { bridge_.unsubscribe(id); }
  void set_cost_function(sdk::R2rCostFunction cost) override { bridge_.set_cost(this, std::move(cost)); }
  const std::string& owner() const noexcept { return owner_; }

 private:
  PluginBridge& bridge_;
  sdk::Worker& worker_;
  std::string owner_;
};

PluginBridge::~PluginBridge() { detach(); }

void PluginBridge::attach(R2rNode& node) {
  detach();
  std::vector<std::uint64_t> ids;
  for (r2r_wire::MessageType type : kAllTypes)
    ids.push_back(node.subscribe(type, [this](const ReceivedMessage& m) { deliver(m); }));
  std::lock_guard lock(mutex_);
  node_ = &node;
  node_subscriptions_ = std::move(ids);
}

void PluginBridge::detach() noexcept {
  R2rNode* node = nullptr;
  std::vector<std::uint64_t> ids;
  {
    std::lock_guard lock(mutex_);
    node = std::exchange(node_, nullptr);
    ids = std::move(node_subscriptions_);
    node_subscriptions_.clear();
  }
  if (node == nullptr) return;
  for (std::uint64_t id : ids) node->unsubscribe(id);
}

std::unique_ptr<sdk::R2rLink> PluginBridge::make_link(sdk::Worker& worker, std::string owner) {
  return std::make_unique<Link>(*this, worker, std::move(owner));
}

void PluginBridge::deliver(const ReceivedMessage& m) {
  // Built once, shared by every subscriber's queued task.
  auto message = std::make_shared<const sdk::R2rMessage>(
      sdk::R2rMessage{std::string(type_name(m.envelope.type)), m.envelope.source_id, m.envelope.target_id, m.envelope.timestamp,
                      m.envelope.payload, m.principal, m.transport});
  std::lock_guard lock(mutex_);
  for (const auto& [id, entry] : subscriptions_) {
    const Subscription& sub = entry.second;
    if (sub.type != m.envelope.type) continue;
    sub.worker->post([callback = sub.callback, live = sub.live, message] {
      if (*live) callback(*message);  // an exception is the worker's: logged, and the plugin marked failed
    });
  }
}

sdk::R2rSendResult PluginBridge::send(std::string_view type, const sdk::Json& payload, const std::optional<std::string>& target) {
  const auto parsed = r2r_wire::parse_message_type(type);
  if (!parsed) return {false, "unknown R2R message type '" + std::string(type) + "'", "/type"};
  R2rNode* node = nullptr;
  {
    std::lock_guard lock(mutex_);
    node = node_;
  }
  // Sent without the lock: a transport may deliver synchronously back into deliver(). The node outlives every
  // plugin worker (the kernel joins them before destroying it), so the pointer stays good for this call.
  if (node == nullptr) return {false, "R2R is not running on this robot", ""};
  auto sent = node->send(*parsed, payload, target);
  if (auto* error = std::get_if<r2r_wire::R2rError>(&sent)) return {false, error->message, error->field};
  return {true, "", ""};
}

std::uint64_t PluginBridge::subscribe(const Link* owner, std::string_view type, sdk::R2rLink::Callback callback,
                                      sdk::Worker& worker) {
  const auto parsed = r2r_wire::parse_message_type(type);
  if (!parsed) throw std::invalid_argument("unknown R2R message type '" + std::string(type) + "'");
  if (!callback) throw std::invalid_argument("R2R subscribe needs a callback");
  std::lock_guard lock(mutex_);
  const std::uint64_t id = next_id_++;
  subscriptions_.emplace(
      id, std::make_pair(owner, Subscription{*parsed, &worker, std::move(callback), std::make_shared<bool>(true)}));
  return id;
}

void PluginBridge::unsubscribe(std::uint64_t id) noexcept {
  std::lock_guard lock(mutex_);
  if (const auto it = subscriptions_.find(id); it != subscriptions_.end()) {
    *it->second.second.live = false;
    subscriptions_.erase(it);
  }
}

void PluginBridge::set_cost(const Link* owner, sdk::R2rCostFunction cost) {
  {
    std::lock_guard lock(mutex_);
    cost_owner_ = cost ? owner : nullptr;
    cost_ = std::move(cost);
    ++cost_generation_;
  }
  sync_cost();
}

void PluginBridge::sync_cost(bool again) noexcept {
  try {
    std::lock_guard sync(sync_mutex_);
    const sdk::FleetAuctions* fleet = fleet_ ? fleet_() : nullptr;
    if (fleet == nullptr) return;  // handed on once the fleet plugin offers its service
    sdk::R2rCostFunction cost;
    std::uint64_t generation = 0;
    {
      std::lock_guard lock(mutex_);
      cost = cost_;
      generation = cost_generation_;
    }
    if (!again && fleet == synced_fleet_ && generation == synced_generation_) return;
    fleet->set_cost_override(std::move(cost));
    synced_fleet_ = fleet;
    synced_generation_ = generation;
  } catch (const std::exception& e) {
    spdlog::warn("r2r: a plugin's bid price could not be handed to the fleet plugin: {}", e.what());
  }
}

void PluginBridge::forget(const Link* owner) noexcept {
  bool price_gone = false;
  {
    std::lock_guard lock(mutex_);
    for (auto it = subscriptions_.begin(); it != subscriptions_.end();) {
      if (it->second.first == owner) {
        *it->second.second.live = false;
        it = subscriptions_.erase(it);
      } else {
        ++it;
      }
    }
    if (cost_owner_ == owner) {  // the instance is going away: its cost function must not be called again
      cost_owner_ = nullptr;
      cost_ = nullptr;
      ++cost_generation_;
      price_gone = true;
    }
  }
  if (price_gone) sync_cost();
}

}  // namespace rcand::services::r2r
