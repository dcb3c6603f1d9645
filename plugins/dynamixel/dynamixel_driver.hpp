// Driver protocol "dynamixel" (alias "dynamixel_v2"): Dynamixel Protocol 2.0 servos on one serial bus, as an arm
// (JointArm: joints in position mode) and/or a differential drive (wheels in velocity mode), chosen by the config.
// Its interface is differential_drive when wheels are configured (teleop and nav find it; the arm reaches its joints
// by cross-cast), joint_arm otherwise.
//
// Every command is one sync write; the status is one sync read per poll; halt() is one sync write of the block
// goal velocity .. goal position for every servo: wheels to 0, joints held where they are with the torque on (an
// arm whose torque drops falls under gravity). The poll is also the Bus Watchdog's keep-alive: if rcand dies or the
// cable is cut, every servo stops by itself after watchdog_ms.
#pragma once

#include <rcand/sdk/bus_worker.hpp>
#include <rcand/sdk/interfaces/arm.hpp>
#include <rcand/sdk/plugin.hpp>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "dxl_bus.hpp"
#include "models.hpp"
#include "settings.hpp"

namespace rcand::plugins::dynamixel {

// Owns the bus; halt interrupts a poll waiting for replies (DxlBus is an sdk::InterruptibleBus).
using SerialWorker = sdk::BusWorker<DxlBus>;
static_assert(sdk::InterruptibleBus<DxlBus>);

class DynamixelDriver final : public sdk::DifferentialDrive, public sdk::JointArm {
 public:
  DynamixelDriver(DynamixelSettings settings, std::shared_ptr<SerialLink> link, sdk::Logger* log = nullptr);
  ~DynamixelDriver() override;

  std::string_view interface_name() const noexcept override;
  // Pings every servo (a missing one is a named fault listing what a scan found), checks its model and Hardware
  // Error Status, sets its operating mode, holds it where it is with the torque on, then arms the Bus Watchdog.
  void start() override;
  void set_wheel_speeds(double left, double right) override;
  void set_joint_targets(const std::vector<sdk::JointTarget>& targets) override;
  std::vector<sdk::JointState> joint_states() const override;
  void halt() noexcept override;
  void shutdown() noexcept override;  // halt; the watchdog stays armed, so the servos stop once rcand stops talking
  nlohmann::json status() const override;

  // Reboots one servo (clears a latched hardware error; its torque drops while it restarts) and brings it back
  // holding its position. Throws DxlError / std::invalid_argument for an unknown id.
  void reboot_servo(std::uint8_t id);
  std::string fail_safe() const;
  std::uint64_t polls() const;

 private:
  struct Servo {
    ServoSettings config;
    Model model{};
    double min_deg = -180.0, max_deg = 180.0;
    std::int32_t velocity_limit = 0;  // units
    std::uint32_t profile_acceleration = 0;
    std::int32_t profile_velocity = 0;  // units, as last written
    std::int32_t goal_ticks = 0;        // joints
    std::int32_t goal_velocity = 0;     // wheels, units
    double commanded_dps = 0.0;
    std::optional<std::int32_t> present_ticks;
    std::int32_t present_velocity = 0;
    std::chrono::steady_clock::time_point read_at{};
    unsigned missed_polls = 0;
    std::uint8_t hardware_error = 0;
    bool torque_on = false;
  };

  // Runs `job` on the worker; throws on failure or timeout.
  void run(SerialWorker::Job job, std::chrono::milliseconds deadline, const char* what);
  // Worker thread: one servo from power-up state to holding, torque on. Updates `servo` (not yet shared).
  void init_servo(DxlBus& bus, Servo& servo) const;
  void poll(DxlBus& bus);
  std::int32_t hold_ticks(const Servo& servo, std::chrono::steady_clock::time_point now) const;
  std::int32_t wheel_units(const Servo& servo, double fraction) const;

  const DynamixelSettings settings_;
  const std::shared_ptr<SerialLink> link_;
  sdk::Logger* const log_;
  const std::shared_ptr<DxlBus> bus_;
  const ControlTable* table_ = &kTableX;
  std::unique_ptr<SerialWorker> worker_;

  const std::shared_ptr<std::atomic<std::uint64_t>> generation_ = std::make_shared<std::atomic<std::uint64_t>>(0);
  mutable std::mutex mutex_;  // the fields below; never held while waiting for the bus
  std::vector<Servo> servos_;
  bool started_ = false;
  std::optional<int> latency_timer_ms_;
  std::uint64_t commands_ = 0, halts_ = 0, halts_unconfirmed_ = 0, polls_ = 0, poll_failures_ = 0;
  std::string last_error_;
};

}  // namespace rcand::plugins::dynamixel
