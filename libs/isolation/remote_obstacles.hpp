// The obstacle zones an isolated capability offers (sdk::ObstacleSource: vision's depth), carried to rcand, where nav
// reads them every 25 ms and must never wait on another process. The host polls the plugin's source and sends each new
// reading (ObstaclePoller); rcand offers a RemoteObstacles that answers from the newest one, and from the moment the
// host dies, "not available" (nav then stops, as for a camera that went down).
#pragma once

#include <nlohmann/json.hpp>

#include <chrono>
#include <condition_variable>
#include <mutex>
#include <thread>

#include "libs/isolation/channel.hpp"
#include "rcand/sdk/interfaces/obstacle_source.hpp"

namespace rcand::isolation {

// rcand's side.
class RemoteObstacles final : public sdk::ObstacleSource {
 public:
  sdk::ObstacleReading obstacles() const noexcept override;
  void update(const nlohmann::json& message);  // an "obstacles" message; throws nlohmann's exception if malformed
  void lost() noexcept;                        // the host ended

 private:
  mutable std::mutex mutex_;
  sdk::ObstacleReading reading_;
};

// The host's side: a thread that reads `source` every kPeriod and sends what changed, until destroyed.
class ObstaclePoller {
 public:
  static constexpr std::chrono::milliseconds kPeriod{10};
  ObstaclePoller(Channel& channel, const sdk::ObstacleSource& source);
  ~ObstaclePoller();
  ObstaclePoller(const ObstaclePoller&) = delete;
  ObstaclePoller& operator=(const ObstaclePoller&) = delete;

 private:
  void run();
  Channel& channel_;
  const sdk::ObstacleSource& source_;
  std::mutex mutex_;
  std::condition_variable stop_;
  bool stopping_ = false;
  std::thread thread_;
};

}  // namespace rcand::isolation
