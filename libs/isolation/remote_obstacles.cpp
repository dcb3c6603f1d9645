#include "libs/isolation/remote_obstacles.hpp"

namespace rcand::isolation {

using nlohmann::json;

sdk::ObstacleReading RemoteObstacles::obstacles() const noexcept {
  std::lock_guard lock(mutex_);
  return reading_;
}

void RemoteObstacles::update(const json& message) {
  const json& r = message.at("r");
  const sdk::ObstacleReading reading{r.at(0).get<bool>(),   r.at(1).get<double>(), r.at(2).get<double>(),
                                     r.at(3).get<double>(), r.at(4).get<double>(), r.at(5).get<std::int64_t>()};
  std::lock_guard lock(mutex_);
  reading_ = reading;
}

void RemoteObstacles::lost() noexcept {
  std::lock_guard lock(mutex_);
  reading_.available = false;
}

ObstaclePoller::ObstaclePoller(Channel& channel, const sdk::ObstacleSource& source)
    : channel_(channel), source_(source), thread_([this] { run(); }) {}

ObstaclePoller::~ObstaclePoller() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  stop_.notify_all();
  thread_.join();
}

void ObstaclePoller::run() {
  sdk::ObstacleReading last;
  bool first = true;
  std::unique_lock lock(mutex_);
  while (!stop_.wait_for(lock, kPeriod, [&] { return stopping_; })) {
    const auto now = source_.obstacles();
    if (!first && now.available == last.available && now.timestamp_ms == last.timestamp_ms && now.nearest_cm == last.nearest_cm)
      continue;
    first = false;
    last = now;
    channel_.send(
        {{"t", "obstacles"}, {"r", {now.available, now.left_cm, now.center_cm, now.right_cm, now.nearest_cm, now.timestamp_ms}}},
        nullptr, /*wait=*/false);
  }
}

}  // namespace rcand::isolation
