// Driver protocol "feetech": Feetech STS serial bus servos (the STS3215 of the SO-ARM100/101) on one serial bus, as an
// arm (JointArm: joints in position mode) and/or a differential drive (wheels in wheel/constant-speed mode), chosen
// by the config. Its interface is differential_drive when wheels are configured, joint_arm otherwise.
//
// Every command is one sync write of the block goal position .. torque limit (42..49); the status is one sync read
// of present position .. temperature (56..63) per poll; halt() is one sync write of that block for every servo:
// wheels to speed 0, joints held where they are with the torque on (an arm whose torque drops falls under gravity).
// A servo that misses lost_after_polls status reads in a row is lost: a named fault (its id and the port) in status().
//
// The fail-safe, honestly: STS servos have no bus watchdog. If rcand dies mid-motion, every joint finishes its last
// move and holds there (torque on), and every wheel keeps turning at its last speed until power is cut. The driver
// says so at start (a warning when wheels are configured) and in status().fail_safe; a wheeled robot on STS servos
// needs a physical e-stop that cuts the servo supply.
#pragma once

#include <rcand/sdk/bus_worker.hpp>
#include <rcand/sdk/interfaces/arm.hpp>
#include <rcand/sdk/logger.hpp>
#include <rcand/sdk/plugin.hpp>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "feetech_bus.hpp"
#include "settings.hpp"
#include "sts_table.hpp"

namespace rcand::plugins::feetech {

using FeetechWorker = sdk::BusWorker<FeetechBus>;
static_assert(sdk::InterruptibleBus<FeetechBus>);

class FeetechDriver final : public sdk::DifferentialDrive, public sdk::JointArm {
 public:
  FeetechDriver(FeetechSettings settings, std::shared_ptr<SerialLink> link, sdk::Logger* log = nullptr);
  ~FeetechDriver() override;

  std::string_view interface_name() const noexcept override;
  // Pings every servo (a missing one is a named fault naming its id and the port), checks its model, sets its
  // operating mode, holds it where it is with its torque limit and the torque on.
  void start() override;
  void set_wheel_speeds(double left, double right) override;
  void set_joint_targets(const std::vector<sdk::JointTarget>& targets) override;
  std::vector<sdk::JointState> joint_states() const override;
  void halt() noexcept override;
  void shutdown() noexcept override;  // halt: joints hold, wheels stop; the torque stays on
  nlohmann::json status() const override;

  // Torque limit of one joint or wheel (its name), percent of stall torque, written at once (one sync write).
  void set_torque_limit(const std::string& name, double percent);
  std::string fail_safe() const;
  std::uint64_t polls() const;

 private:
  struct Servo {
    FeetechServoSettings config;
    Model model{};
    double min_deg = -180.0, max_deg = 180.0;
    std::int32_t goal_ticks = 2048;     // joints
    std::int32_t speed = 0;             // goal speed, steps/s (joints: the travel speed, never 0 = "as fast as it can")
    std::uint16_t torque_limit = 1000;  // 0.1 %
    double commanded_dps = 0.0;
    std::optional<std::int32_t> present_ticks;
    std::int32_t present_speed = 0;
    std::int32_t present_load = 0;  // 0.1 %
    double voltage = 0.0;
    int temperature_c = 0;
    std::chrono::steady_clock::time_point read_at{};
    unsigned missed_polls = 0;
    bool lost = false;
    std::uint8_t error = 0;  // the last status error byte
    bool torque_on = false;
  };

  void run(FeetechWorker::Job job, std::chrono::milliseconds deadline, const char* what);
  void init_servo(FeetechBus& bus, Servo& servo) const;  // worker thread; `servo` not yet shared
  void poll(FeetechBus& bus);
  void sync_command(SyncItems items, const char* what);  // one sync write of the command block, unless a halt came first
  std::vector<std::uint8_t> block(const Servo& servo, std::int32_t goal_ticks, std::int32_t speed) const;
  std::int32_t ticks_of(const Servo& servo, double deg) const;
  double degrees_of(const Servo& servo, std::int32_t ticks) const;
  std::int32_t hold_ticks(const Servo& servo, std::chrono::steady_clock::time_point now) const;
  std::int32_t wheel_speed(const Servo& servo, double fraction) const;
  std::int32_t joint_speed(const Servo& servo, double dps) const;
  std::string who(const Servo& servo) const;
  std::string fault_locked() const;  // requires mutex_

  const FeetechSettings settings_;
  const std::shared_ptr<SerialLink> link_;
  sdk::Logger* const log_;
  const std::shared_ptr<FeetechBus> bus_;
  std::unique_ptr<FeetechWorker> worker_;

  const std::shared_ptr<std::atomic<std::uint64_t>> generation_ = std::make_shared<std::atomic<std::uint64_t>>(0);
  mutable std::mutex mutex_;  // the fields below; never held while waiting for the bus
  std::vector<Servo> servos_;
  bool started_ = false;
  std::uint64_t commands_ = 0, halts_ = 0, halts_unconfirmed_ = 0, polls_ = 0, poll_failures_ = 0;
  std::string last_error_;
};

}  // namespace rcand::plugins::feetech
