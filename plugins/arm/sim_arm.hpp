// A simulated arm (protocol "sim_arm"): each joint travels to its target at its commanded speed on the clock, so
// tests and the bundled robot can prove where the arm was and when. halt() holds the present position with the
// torque on, as a real arm must (dropping torque lets it fall under gravity).
#pragma once

#include <rcand/sdk/interfaces/arm.hpp>
#include <rcand/sdk/plugin.hpp>
#include <rcand/sdk/status_publisher.hpp>

#include <chrono>
#include <cstdint>
#include <deque>
#include <mutex>
#include <string>
#include <vector>

#include "joint_limits.hpp"

namespace rcand::plugins::arm {

class SimArm final : public sdk::ActuatorDriver, public sdk::JointArm {
 public:
  static constexpr std::size_t kTimelineCapacity = 4096;
  static constexpr std::size_t kStatusEvents = 64;
  static constexpr std::chrono::milliseconds kPublishPeriod{100};  // while a joint moves, 10 Hz

  struct Event {
    std::int64_t t_us;
    std::string cause;                  // "command" | "halt"
    std::vector<double> positions_deg;  // every joint at that instant, in joint order
    std::vector<double> targets_deg;
  };

  // `joints` must not be empty. With `publish_to`, the status is published from its "status" worker while moving.
  SimArm(const sdk::Clock& clock, std::vector<JointLimit> joints, sdk::PluginContext* publish_to = nullptr);

  std::string_view interface_name() const noexcept override { return kInterface; }
  void set_joint_targets(const std::vector<sdk::JointTarget>& targets) override;
  std::vector<sdk::JointState> joint_states() const override;
  // Any thread; waits only on this driver's mutex. Every joint stops where it is now; torque stays on.
  void halt() noexcept override;
  nlohmann::json status() const override;

  std::vector<Event> timeline() const;
  std::uint64_t commands() const;
  std::uint64_t halts() const;
  const std::vector<JointLimit>& joints() const noexcept { return limits_; }

 private:
  struct Motion {
    double from_deg;
    double target_deg;
    double velocity_dps;  // 0: holding
    std::int64_t since_us;
  };
  // Requires mutex_.
  double position_at(const Motion& m, std::int64_t now_us) const noexcept;
  void record(const char* cause, std::int64_t now_us);
  nlohmann::json status_locked() const;
  bool moving_locked(std::int64_t now_us) const noexcept;

  const sdk::Clock& clock_;
  const std::vector<JointLimit> limits_;
  mutable std::mutex mutex_;    // this driver's state only: halt() never waits on anything else
  std::vector<Motion> motion_;  // parallel to limits_
  std::deque<Event> timeline_;
  std::uint64_t commands_ = 0;
  std::uint64_t halts_ = 0;
  std::uint64_t changes_ = 0;

  sdk::StatusPublisher publisher_;  // last: its tasks read the state above
};

}  // namespace rcand::plugins::arm
