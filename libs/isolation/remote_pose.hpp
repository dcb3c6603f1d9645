// The robot's pose (sdk::PoseSource: nav's) as an isolated capability's host sees it: rcand sends its reading with
// every request and every heartbeat, so a handler reads the pose as it was when its request left rcand (and at most
// one heartbeat old otherwise) without a round trip. Present only when rcand has a pose source.
#pragma once

#include <nlohmann/json.hpp>

#include <atomic>
#include <mutex>
#include <optional>

#include "rcand/sdk/interfaces/pose_source.hpp"

namespace rcand::isolation {

inline nlohmann::json encode_pose(const sdk::PoseReading& r) {
  return {r.available, r.pose.x_m, r.pose.y_m, r.pose.heading_deg, r.busy};
}

class RemotePose final : public sdk::PoseSource {
 public:
  sdk::PoseReading read() const noexcept override {
    std::lock_guard lock(mutex_);
    return reading_;
  }
  // A message's "pose", when it has one: rcand has a pose source from then on. Throws nlohmann's exception if malformed.
  void update(const nlohmann::json& message) {
    const auto it = message.find("pose");
    if (it == message.end()) return;
    const sdk::PoseReading reading{it->at(0).get<bool>(),
                                   {it->at(1).get<double>(), it->at(2).get<double>(), it->at(3).get<double>()},
                                   it->at(4).get<bool>()};
    std::lock_guard lock(mutex_);
    reading_ = reading;
    known_.store(true);
  }
  bool known() const noexcept { return known_.load(); }

 private:
  mutable std::mutex mutex_;
  sdk::PoseReading reading_;
  std::atomic<bool> known_{false};
};

}  // namespace rcand::isolation
