// A simulated differential drive (protocol "sim_diff_drive"): records every command and halt on a timeline
// and dead-reckons a pose, so tests and the integration suite can prove what the motors did.
#pragma once

#include <rcand/sdk/plugin.hpp>
#include <rcand/sdk/status_publisher.hpp>

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <mutex>
#include <string>
#include <vector>

namespace rcand::plugins::sim_drive {

struct SimDriveSettings {
  double max_wheel_rps = 1.0;          // full speed, in wheel revolutions per second
  double wheel_circumference_m = 0.21;
  double wheel_base_m = 0.15;          // distance between the wheels, for turning
  int fail_after_commands = 0;         // drills: from the Nth set_wheel_speeds on, throw (0 = never)
  int halt_delay_ms = 0;               // drills: halt() sleeps this long before zeroing (0 = none)

  // The driver's settings first, then the robot config's physics block, then the defaults above.
  // Throws sdk::ConfigError naming the key when a value has the wrong type or is out of range.
  static SimDriveSettings from(const sdk::PluginContext& ctx);
};

class SimDrive final : public sdk::DifferentialDrive {
 public:
  static constexpr std::size_t kTimelineCapacity = 4096;  // newest events kept
  static constexpr std::size_t kStatusEvents = 256;       // events shown by status()
  static constexpr std::chrono::milliseconds kPublishPeriod{100};  // while the wheels turn the pose moves: 10 Hz

  struct Event {
    std::int64_t t_us;
    double left;
    double right;
    std::string cause;  // "command" | "halt"
  };
  struct Pose {
    double x_m = 0.0;
    double y_m = 0.0;
    double heading_rad = 0.0;  // unwrapped; heading_deg() folds it into (-180, 180]
    double heading_deg() const;
  };

  // With `publish_to` (the plugin passes its context), the status is published (PluginContext::publish_status)
  // from the context's worker "status": at the first command after a stop, then every kPublishPeriod while the
  // wheels turn or something changed, ending with the stopped state (without the timeline, which status() has).
  // halt() adds nothing to the stop path: the publishing already running (the wheels were turning) picks the halt up.
  SimDrive(const sdk::Clock& clock, SimDriveSettings settings, sdk::PluginContext* publish_to = nullptr);

  // Handler or worker thread, through the motion gate. Clamps to [-1, 1]. Throws from the Nth command on
  // when fail_after_commands is set, recording nothing.
  void set_wheel_speeds(double left, double right) override;
  // Any thread; waits only on this driver's own mutex (after the optional drill delay).
  void halt() noexcept override;
  // Any thread, never blocks beyond the driver's mutex.
  nlohmann::json status() const override;

  Pose pose() const;  // integrated up to now
  std::vector<Event> timeline() const;
  double left() const;
  double right() const;
  std::uint64_t commands() const;
  std::uint64_t halts() const;
  const SimDriveSettings& settings() const noexcept { return settings_; }

 private:
  // Requires mutex_. The pose at `now_us` assuming the current wheel speeds since the last event.
  Pose pose_at(std::int64_t now_us) const;
  // Requires mutex_. Integrates up to now, applies the speeds and records the event.
  void apply(double left, double right, const char* cause);
  // Requires mutex_. The published status leaves the timeline out: rcand shows no driver's published status (only
  // its fault), and a status a drive publishes at 10 Hz while moving should not grow with its history.
  nlohmann::json status_locked(bool with_timeline) const;

  const sdk::Clock& clock_;
  const SimDriveSettings settings_;
  mutable std::mutex mutex_;  // this driver's state only: halt() never waits on anything else
  double left_ = 0.0;
  double right_ = 0.0;
  Pose pose_;
  std::int64_t pose_us_;
  std::int64_t zero_since_us_;
  std::uint64_t commands_ = 0;
  std::uint64_t halts_ = 0;
  std::uint64_t attempts_ = 0;  // set_wheel_speeds calls, failed ones included (for fail_after_commands)
  std::deque<Event> timeline_;
  std::uint64_t changes_ = 0;  // bumped by every apply(), so the publisher sees what it has not published yet

  sdk::StatusPublisher publisher_;  // last: its tasks read the state above
};

}  // namespace rcand::plugins::sim_drive
