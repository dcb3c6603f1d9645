#include "hitl.hpp"

#include <algorithm>

namespace rcand::plugins::chat {

std::vector<HitlGate> read_hitl_gates(const sdk::ConfigView& robot_config) {
  const auto& raw = robot_config.raw();
  const auto agent = raw.find("agent");
  if (agent == raw.end() || !agent->is_object() || !agent->contains("hitl_gates")) return {};
  const auto& list = agent->at("hitl_gates");
  if (list.is_null()) return {};
  if (!list.is_array()) throw sdk::ConfigError("agent.hitl_gates: expected a list of gates");
  std::vector<HitlGate> gates;
  for (std::size_t i = 0; i < list.size(); ++i) {
    const std::string where = "agent.hitl_gates[" + std::to_string(i) + "]";
    const auto& item = list[i];
    if (!item.is_object())
      throw sdk::ConfigError(where + ": expected a mapping {capabilities?, scope?, timeout_ms?, on_timeout?}");
    HitlGate gate;
    for (const auto& [key, value] : item.items()) {
      if (key == "capabilities") {
        if (!value.is_array()) throw sdk::ConfigError(where + ".capabilities: a list of capability names");
        for (const auto& name : value) {
          if (!name.is_string()) throw sdk::ConfigError(where + ".capabilities: a list of capability names");
          gate.capabilities.push_back(name.get<std::string>());
        }
      } else if (key == "scope") {
        gate.scope = value.is_string() ? sdk::parse_scope(value.get<std::string>()) : std::nullopt;
        if (!gate.scope) throw sdk::ConfigError(where + ".scope: a scope name (status, control, ...)");
      } else if (key == "timeout_ms") {
        if (!value.is_number_integer() || value.get<long long>() < 1 || value.get<long long>() > 3600000)
          throw sdk::ConfigError(where + ".timeout_ms: an integer in [1, 3600000]");
        gate.timeout = std::chrono::milliseconds(value.get<long long>());
      } else if (key == "on_timeout") {
        const std::string text = value.is_string() ? value.get<std::string>() : "";
        if (text != "deny" && text != "approve") throw sdk::ConfigError(where + ".on_timeout: deny or approve");
        gate.approve_on_timeout = text == "approve";
      } else {
        throw sdk::ConfigError(where + "." + key + ": unknown key (capabilities, scope, timeout_ms, on_timeout)");
      }
    }
    gates.push_back(std::move(gate));
  }
  return gates;
}

const HitlGate* matching_hitl_gate(const std::vector<HitlGate>& gates, sdk::Scope scope, const std::string& capability) {
  for (const auto& gate : gates) {
    if (gate.scope && *gate.scope != scope) continue;
    if (!gate.capabilities.empty() &&
        std::find(gate.capabilities.begin(), gate.capabilities.end(), capability) == gate.capabilities.end())
      continue;
    return &gate;
  }
  return nullptr;
}

HitlQueue::Admission HitlQueue::add(const std::string& thought_id, sdk::Json summary, Decide decide, std::uint64_t epoch,
                                    const std::string& principal, bool privileged) {
  std::lock_guard lock(mutex_);
  if (waits_.size() >= limits_.limit) return Admission::Full;
  if (!privileged) {
    if (waits_.size() + limits_.reserved >= limits_.limit) return Admission::Reserved;
    const auto held = std::count_if(waits_.begin(), waits_.end(), [&](const auto& w) { return w.second.principal == principal; });
    if (static_cast<std::size_t>(held) >= limits_.per_principal) return Admission::OverShare;
  }
  waits_[thought_id] = Wait{++seq_, std::move(summary), std::move(decide), 0, epoch, principal};
  return Admission::Added;
}

bool HitlQueue::set_timer(const std::string& thought_id, std::uint64_t timer) {
  std::lock_guard lock(mutex_);
  const auto it = waits_.find(thought_id);
  if (it == waits_.end()) return false;
  it->second.timer = timer;
  return true;
}

std::optional<HitlQueue::Taken> HitlQueue::take(const std::string& thought_id) {
  std::lock_guard lock(mutex_);
  const auto it = waits_.find(thought_id);
  if (it == waits_.end()) return std::nullopt;
  Taken taken{std::move(it->second.decide), it->second.timer};
  waits_.erase(it);
  return taken;
}

std::vector<HitlQueue::Taken> HitlQueue::take_all(std::uint64_t epoch) {
  std::lock_guard lock(mutex_);
  std::vector<Taken> all;
  for (auto it = waits_.begin(); it != waits_.end();) {
    if (it->second.epoch >= epoch) {
      ++it;
      continue;
    }
    all.push_back({std::move(it->second.decide), it->second.timer});
    it = waits_.erase(it);
  }
  return all;
}

sdk::Json HitlQueue::list() const {
  std::lock_guard lock(mutex_);
  std::vector<const Wait*> ordered;
  for (const auto& [id, wait] : waits_) ordered.push_back(&wait);
  std::sort(ordered.begin(), ordered.end(), [](const Wait* a, const Wait* b) { return a->seq < b->seq; });
  sdk::Json list = sdk::Json::array();
  for (const Wait* wait : ordered) list.push_back(wait->summary);
  return list;
}

std::size_t HitlQueue::size() const {
  std::lock_guard lock(mutex_);
  return waits_.size();
}

const char* decision_name(HitlQueue::Decision decision) noexcept {
  switch (decision) {
    case HitlQueue::Decision::Approve: return "approved";
    case HitlQueue::Decision::Deny: return "denied";
    case HitlQueue::Decision::Timeout: return "timed_out";
    case HitlQueue::Decision::Estop: return "cancelled_by_estop";
    case HitlQueue::Decision::Shutdown: return "cancelled_by_shutdown";
  }
  return "denied";
}

}  // namespace rcand::plugins::chat
