// Driver protocol "arduino_serial_json": a differential drive behind an Arduino running the reference runtime's
// bridge firmware (an L298N on the board's pins), over its USB serial port (protocol.hpp).
//
// - One BusWorker owns the port. A command is one line and its ack; halt() is {"cmd":"stop"} written as the worker's
//   urgent job, which cuts short a wait for a reply in progress and returns by halt_deadline_ms even when the port
//   is hung (the stop is then unconfirmed, and the firmware's own watchdog is what stops the motors).
// - The firmware stops the motors when no line came for 1 s. While the drive is non-zero the worker resends the
//   current drive command every heartbeat_ms (default 250); while stopped it sends nothing for the drive, so a
//   stopped robot stays stopped whatever happens to rcand. If rcand dies or the cable is cut, the motors stop within
//   1 s by the firmware's watchdog.
// - With an `ultrasonic` block the worker polls {"cmd":"sensor","id":...} at poll_hz and the driver offers the
//   readings as the robot's obstacle source (sdk::ObstacleSource, what nav and teleop check): the distance in every
//   zone (one beam has no left and right), unavailable when stale, absent or without echo (fail safe, as depth).
#pragma once

#include <rcand/sdk/bus_worker.hpp>
#include <rcand/sdk/interfaces/obstacle_source.hpp>
#include <rcand/sdk/plugin.hpp>

#include <chrono>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "serial_bus.hpp"
#include "settings.hpp"

namespace rcand::plugins::arduino {

using ArduinoWorker = sdk::BusWorker<ArduinoBus>;
static_assert(sdk::InterruptibleBus<ArduinoBus>);

// What the worker and the driver share: lives as long as the last job that may still run (a detached worker).
struct ArduinoState {
  std::mutex mutex;
  bool started = false;
  int left_pwm = 0, right_pwm = 0;  // the command in force
  std::uint64_t generation = 0;     // bumped by halt: a drive queued before it is stale
  std::chrono::steady_clock::time_point last_drive_sent{}, last_poll{};
  std::optional<std::int64_t> distance_mm;  // the last reading (-1: no echo)
  std::chrono::steady_clock::time_point read_at{};
  std::int64_t read_wall_ms = 0;
  std::uint64_t commands = 0, heartbeats = 0, halts = 0, halts_unconfirmed = 0, polls = 0, poll_failures = 0;
  std::string last_error;
};

// The ultrasonic's readings as the robot's obstacle zones.
class UltrasonicZones final : public sdk::ObstacleSource {
 public:
  UltrasonicZones(std::shared_ptr<ArduinoState> state, UltrasonicSettings settings);
  sdk::ObstacleReading obstacles() const noexcept override;

 private:
  const std::shared_ptr<ArduinoState> state_;
  const UltrasonicSettings settings_;
};

class ArduinoDriver final : public sdk::DifferentialDrive {
 public:
  // Opens the port (a missing one is a named fault). `ctx` (optional) is where the ultrasonic is offered.
  ArduinoDriver(ArduinoSettings settings, std::shared_ptr<ArduinoBus> bus, sdk::Logger* log = nullptr,
                sdk::PluginContext* ctx = nullptr);
  ~ArduinoDriver() override;

  // Pings until the sketch answers (the board resets when the port opens), bounded by boot_timeout_ms; then reads
  // the ultrasonic once and offers it. Throws sdk::DeviceFault: "no answer from the Arduino on ... is the bridge
  // firmware flashed?".
  void start() override;
  void set_wheel_speeds(double left, double right) override;
  void halt() noexcept override;
  void shutdown() noexcept override;  // halt; the firmware's watchdog covers the rest
  nlohmann::json status() const override;

  const UltrasonicZones* ultrasonic() const noexcept { return zones_.get(); }
  std::string fail_safe() const;

 private:
  void run(ArduinoWorker::Job job, std::chrono::milliseconds deadline, const char* what);

  const ArduinoSettings settings_;
  sdk::Logger* const log_;
  sdk::PluginContext* const ctx_;
  const std::shared_ptr<ArduinoBus> bus_;
  const std::shared_ptr<ArduinoState> state_ = std::make_shared<ArduinoState>();
  std::unique_ptr<UltrasonicZones> zones_;
  std::unique_ptr<ArduinoWorker> worker_;
};

}  // namespace rcand::plugins::arduino
