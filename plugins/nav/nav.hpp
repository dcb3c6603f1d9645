// The nav capability (seed §10, docs/protocol.md §8): dead-reckoning waypoints on a differential_drive actuator.
//
// POST /api/nav/waypoint validates, checks the obstacle source, and sends the first wheel command itself (so a job
// that cannot start answers 423/503 with nothing moving); the rest of the job — waiting out the turn, the drive,
// the final stop — runs on the "job" worker. Whatever ends the job (completion, POST /api/nav/cancel, e-stop,
// obstacle, driver exception, shutdown), a scope guard stops the motors. Waits wake at once on cancel or e-stop.
#pragma once

#include <rcand/sdk/interfaces/pose_source.hpp>
#include <rcand/sdk/plugin.hpp>

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "obstacle_guard.hpp"
#include "pose.hpp"
#include "waypoint_plan.hpp"

namespace rcand::plugins::nav {

// Sleeps up to `slice` or until `wake()` is true. The kernel build waits on the capability's own condition
// variable (notified by cancel and on_estop); unit tests on the fake host pass one that advances the manual clock.
using Sleeper = std::function<void(std::chrono::microseconds slice, const std::function<bool()>& wake)>;

// Offers two services (rcand/sdk/services.hpp) while it runs: itself as the robot's PoseSource (the dead-reckoned pose,
// busy while a job runs) and its TripTiming as the TripEstimator.
class Nav final : public sdk::Capability, public sdk::PoseSource {
 public:
  static constexpr std::chrono::milliseconds kObstaclePeriod = obstacle::kCheckPeriod;  // 40 Hz while a job runs
  static constexpr std::chrono::milliseconds kCancelWait{1000};    // cancel waits this long for the job to end
  static constexpr std::chrono::milliseconds kPublishPeriod{100};  // the moving pose is published at most 10 Hz

  // Reads the physics block (throws sdk::ConfigError naming the key), `driver`, `max_job_ms` and the obstacle
  // threshold (agent.min_obstacle_m, else safety.obstacle_stop_cm). `sleeper` null: the condition-variable one.
  explicit Nav(sdk::PluginContext& ctx, Sleeper sleeper = nullptr);

  void start() override;
  std::vector<sdk::Route> routes() override;
  sdk::Json status() const override;
  void on_estop() noexcept override;
  void shutdown() noexcept override;
  // PoseSource: the live pose (with the running phase's progress) and whether a job runs. Any thread.
  sdk::PoseReading read() const noexcept override;

 private:
  enum class End { Elapsed, Cancelled, Estop, Obstacle, Shutdown };
  struct Job {
    std::string id;
    Plan plan;
    std::string driver;
    std::string state;  // turning | driving | done | aborted
    std::int64_t started_us = 0, phase_started_us = 0, ended_us = 0;
    sdk::Json result;  // null while running
    bool phase_open = false;  // the current phase's motion is not yet added to the pose
    double turned_deg = 0.0, driven_m = 0.0;
  };
  struct Refusal {
    sdk::GateStatus gate;  // for the HTTP answer when the first command is refused
    std::string reason, message;
  };

  sdk::Response waypoint(const sdk::Request& request);
  sdk::Response cancel(const sdk::Request& request);
  sdk::Response get_status(const sdk::Request& request) const;

  // Runs on the "job" worker: waits out the phase the handler started, then the next, then stops.
  void run_job(std::uint64_t estop_events) noexcept;
  // Waits until `deadline_us` on the plugin clock; returns early on cancel, e-stop, shutdown, an obstacle or
  // unavailable depth (both End::Obstacle, the verdict in obstacle_stopped_).
  End wait_until(std::int64_t deadline_us, std::uint64_t estop_events);
  // The obstacle check (§10.5, obstacle_guard.hpp): not clear while `moving` latches the e-stop; before the job
  // only an obstacle does (unavailable depth then refuses the job without latching). Returns what was not clear.
  std::optional<obstacle::Verdict> obstacle_stop(bool moving);
  // Sends a phase's wheel command unless the job was cancelled or stopped; OK, or why not.
  std::optional<Refusal> command(const std::string& driver, double left, double right, std::uint64_t estop_events);
  void wake() noexcept;
  bool interrupted(std::uint64_t estop_events) const noexcept;
  // The pose with the running phase's progress up to `now_us` added (requires mutex_).
  Pose live_pose(std::int64_t now_us) const;
  // Adds a phase's progress to the committed pose (requires mutex_).
  void commit_phase(std::int64_t until_us);
  void finish(bool ok, const std::string& reason, const std::string& message);
  // Hands the kernel status() as it is now (PluginContext::publish_status): after every change of the job, and from
  // the job's waits while it moves. Never with mutex_ held.
  void publish() noexcept;
  std::optional<std::string> resolve_driver() const;
  std::string new_job_id();

  sdk::PluginContext& ctx_;
  sdk::Worker& worker_;
  const Physics physics_;
  const TripTiming trips_{physics_};
  const std::optional<std::string> configured_driver_;
  const std::int64_t max_job_us_;
  const obstacle::Guard obstacles_;
  Sleeper sleeper_;

  // Orders a phase's wheel command against cancel's halt, so a cancelled job can never start a new phase.
  // on_estop() never takes it: the kernel halts the drivers itself.
  std::mutex motion_mutex_;
  std::atomic<bool> cancel_requested_{false};
  std::atomic<bool> shutting_down_{false};
  std::atomic<std::uint64_t> estop_events_{0};  // bumped by on_estop; a job remembers the value it started with
  std::mutex wake_mutex_;                       // for wake_cv_ only
  std::condition_variable wake_cv_;

  mutable std::mutex mutex_;  // the fields below; never held while calling the gate, the e-stop or the sleeper
  std::condition_variable ended_cv_;  // a job ended (cancel waits on it)
  bool running_ = false;
  std::optional<Job> job_;  // the running job, or the last one
  Pose pose_;               // committed: every finished phase
  std::uint64_t job_counter_ = 0;
  obstacle::Verdict obstacle_stopped_;  // job worker only: why wait_until returned End::Obstacle
  // The last obstacle check: set by the handler's check before the job, then by the job's waits (one job at a time,
  // and the handler hands over to the job worker through post(), so no two threads use it at once).
  std::int64_t last_obstacle_check_us_ = 0;
  std::atomic<std::int64_t> last_publish_us_{0};
};

}  // namespace rcand::plugins::nav
