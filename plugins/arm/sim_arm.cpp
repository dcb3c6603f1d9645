#include "sim_arm.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace rcand::plugins::arm {

SimArm::SimArm(const sdk::Clock& clock, std::vector<JointLimit> joints, sdk::PluginContext* publish_to)
    : clock_(clock),
      limits_(std::move(joints)),
      publisher_(
          publish_to, kPublishPeriod,
          [this] {
            std::lock_guard lock(mutex_);
            return sdk::StatusPublisher::Snapshot{status_locked(), changes_, moving_locked(clock_.now_us())};
          },
          [this] {
            std::lock_guard lock(mutex_);
            return changes_;
          }) {
  if (limits_.empty()) throw sdk::ConfigError("sim_arm: no joints (give joints[] or physics.kinematics joints)");
  const std::int64_t now = clock_.now_us();
  for (const auto& j : limits_) motion_.push_back({j.home_deg, j.home_deg, 0.0, now});
}

double SimArm::position_at(const Motion& m, std::int64_t now_us) const noexcept {
  if (m.velocity_dps <= 0.0) return m.from_deg;
  const double travelled = m.velocity_dps * static_cast<double>(std::max<std::int64_t>(0, now_us - m.since_us)) / 1e6;
  const double distance = m.target_deg - m.from_deg;
  if (travelled >= std::abs(distance)) return m.target_deg;
  return m.from_deg + std::copysign(travelled, distance);
}

bool SimArm::moving_locked(std::int64_t now_us) const noexcept {
  for (const auto& m : motion_)
    if (position_at(m, now_us) != m.target_deg) return true;
  return false;
}

void SimArm::set_joint_targets(const std::vector<sdk::JointTarget>& targets) {
  {
    std::lock_guard lock(mutex_);
    // Validate everything first: a command is applied whole or not at all.
    std::vector<std::size_t> index;
    for (const auto& t : targets) {
      const auto it = std::find_if(limits_.begin(), limits_.end(), [&](const JointLimit& j) { return j.joint == t.joint; });
      if (it == limits_.end()) throw std::invalid_argument("sim_arm: no joint '" + t.joint + "'");
      if (!std::isfinite(t.position_deg) || t.position_deg < it->min_deg || t.position_deg > it->max_deg)
        throw std::invalid_argument("sim_arm: joint '" + t.joint + "' target " + std::to_string(t.position_deg) +
                                    " is outside [" + std::to_string(it->min_deg) + ", " + std::to_string(it->max_deg) + "]");
      if (!std::isfinite(t.velocity_dps) || t.velocity_dps <= 0.0)
        throw std::invalid_argument("sim_arm: joint '" + t.joint + "' needs a speed > 0");
      index.push_back(static_cast<std::size_t>(it - limits_.begin()));
    }
    const std::int64_t now = clock_.now_us();
    for (std::size_t k = 0; k < targets.size(); ++k) {
      Motion& m = motion_[index[k]];
      m.from_deg = position_at(m, now);
      m.target_deg = targets[k].position_deg;
      // The servo cannot go faster than its rating, whatever it is asked.
      m.velocity_dps = std::min(targets[k].velocity_dps, limits_[index[k]].max_velocity_dps);
      m.since_us = now;
    }
    ++commands_;
    record("command", now);
  }
  publisher_.changed();
}

void SimArm::halt() noexcept {
  std::lock_guard lock(mutex_);
  const std::int64_t now = clock_.now_us();
  for (auto& m : motion_) m = {position_at(m, now), position_at(m, now), 0.0, now};  // hold here, torque on
  ++halts_;
  try {
    record("halt", now);
  } catch (...) {  // only allocation can fail; the joints already hold
  }
}

void SimArm::record(const char* cause, std::int64_t now_us) {
  Event e{now_us, cause, {}, {}};
  for (const auto& m : motion_) {
    e.positions_deg.push_back(position_at(m, now_us));
    e.targets_deg.push_back(m.target_deg);
  }
  timeline_.push_back(std::move(e));
  while (timeline_.size() > kTimelineCapacity) timeline_.pop_front();
  ++changes_;
}

std::vector<sdk::JointState> SimArm::joint_states() const {
  std::lock_guard lock(mutex_);
  const std::int64_t now = clock_.now_us();
  std::vector<sdk::JointState> states;
  for (std::size_t i = 0; i < limits_.size(); ++i) {
    const Motion& m = motion_[i];
    const double at = position_at(m, now);
    const bool moving = at != m.target_deg;
    states.push_back({limits_[i].joint, at, m.target_deg, moving ? m.velocity_dps : 0.0, moving, true});
  }
  return states;
}

nlohmann::json SimArm::status() const {
  std::lock_guard lock(mutex_);
  return status_locked();
}

nlohmann::json SimArm::status_locked() const {
  const std::int64_t now = clock_.now_us();
  nlohmann::json joints = nlohmann::json::array();
  for (std::size_t i = 0; i < limits_.size(); ++i) {
    const double at = position_at(motion_[i], now);
    joints.push_back({{"joint", limits_[i].joint},
                      {"position_deg", at},
                      {"target_deg", motion_[i].target_deg},
                      {"moving", at != motion_[i].target_deg},
                      {"torque_on", true}});
  }
  nlohmann::json events = nlohmann::json::array();
  const std::size_t first = timeline_.size() > kStatusEvents ? timeline_.size() - kStatusEvents : 0;
  for (std::size_t i = first; i < timeline_.size(); ++i)
    events.push_back({{"t_us", timeline_[i].t_us},
                      {"cause", timeline_[i].cause},
                      {"positions_deg", timeline_[i].positions_deg},
                      {"targets_deg", timeline_[i].targets_deg}});
  return {{"joints", std::move(joints)},
          {"moving", moving_locked(now)},
          {"fail_safe", "simulated: halt() holds every joint where it is, torque on"},
          {"now_us", now},
          {"commands", commands_},
          {"halts", halts_},
          {"timeline", std::move(events)}};
}

std::vector<SimArm::Event> SimArm::timeline() const {
  std::lock_guard lock(mutex_);
  return {timeline_.begin(), timeline_.end()};
}
std::uint64_t SimArm::commands() const {
  std::lock_guard lock(mutex_);
  return commands_;
}
std::uint64_t SimArm::halts() const {
  std::lock_guard lock(mutex_);
  return halts_;
}

}  // namespace rcand::plugins::arm
