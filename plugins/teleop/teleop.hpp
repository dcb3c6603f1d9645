// The teleop capability: POST /api/action "move" and "stop" drive a differential_drive actuator through the
// kernel's motion gate. Motion without duration_ms is a dead-man command (§6.2): it stops unless refreshed
// within watchdog_ms.
//
// Depth obstacles (issue 15; the rule is nav's, plugins/nav/obstacle_guard.hpp): a move with linear > 0 is checked
// before it runs and, while depth is in play (obstacle::Guard::in_play), every obstacle::kCheckPeriod (25 ms) while
// it runs. Only forward moves: the depth camera looks forward, so it says nothing about the path of a reverse move,
// and backing away or turning in place (linear <= 0) is how a robot stopped in front of an obstacle gets clear of it
// once an owner has released the e-stop.
#pragma once

#include <rcand/sdk/plugin.hpp>

#include <atomic>
#include <cstdint>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "obstacle_guard.hpp"

namespace rcand::plugins::teleop {

struct WheelMix {
  double left;
  double right;
};
// left = linear - angular, right = linear + angular, scaled down together so neither exceeds 1.
WheelMix mix(double linear, double angular) noexcept;

class Teleop final : public sdk::Capability {
 public:
  static constexpr int kMaxDurationMs = 60'000;

  // Reads `watchdog_ms` (default safety.watchdog_ms, else 500), `driver`, and safety.max_linear_speed.
  // Throws sdk::ConfigError naming the key on a bad value.
  explicit Teleop(sdk::PluginContext& ctx);

  std::vector<sdk::Route> routes() override;
  sdk::Json status() const override;
  void on_estop() noexcept override;
  void shutdown() noexcept override;

 private:
  sdk::Response move(const sdk::Request& request);
  sdk::Response stop(const sdk::Request& request);
  // The configured driver, else the first differential_drive actuator.
  std::optional<std::string> resolve_driver() const;
  // Makes every pending stop timer a no-op and cancels it. Never blocks on motion in progress.
  void disarm() noexcept;
  // Runs on the "motion" worker when a move's duration or dead-man window ends.
  void expire(std::uint64_t generation, const std::string& driver) noexcept;
  // Runs on the "motion" worker every obstacle::kCheckPeriod while a forward move runs: anything but clear latches.
  void watch(std::uint64_t generation) noexcept;
  // Hands the kernel status() as it is now (PluginContext::publish_status), after every change of moving_. Never
  // with state_mutex_ held.
  void publish() noexcept;

  sdk::PluginContext& ctx_;
  sdk::Worker& worker_;
  const int watchdog_ms_;
  const double max_linear_;
  const std::optional<std::string> configured_driver_;
  const obstacle::Guard obstacles_;

  // Orders a move's actuate against a timer's halt, so a stop decided for an older generation can never land
  // after a newer command. on_estop() and stop never take it (they must not wait behind a command).
  std::mutex motion_mutex_;
  // Bumped by every move, stop and e-stop; a timer only acts if its generation is still current.
  std::atomic<std::uint64_t> generation_{0};

  // Publishes from the handler, the motion worker and the e-stop path read and hand over status() one at a time,
  // so an older reading never lands after a newer one.
  std::mutex publish_mutex_;

  mutable std::mutex state_mutex_;  // the fields below; never held while calling into the gate
  std::optional<sdk::TimerId> timer_;
  std::optional<sdk::TimerId> watch_timer_;  // the next obstacle check of a forward move
  bool moving_ = false;
  std::optional<std::int64_t> last_command_us_;
  std::string last_driver_;
};

}  // namespace rcand::plugins::teleop
