// X-series servos speaking Protocol 2.0 on the master side of a pseudo-terminal, for tests and benchmarks: a control
// table per servo (EEPROM writable only with the torque off), ping, read, write, reboot, sync read, sync write, the
// Hardware Error Status with the Alert bit, motion (velocity mode integrates, position mode travels at the profile
// velocity) and the Bus Watchdog: a servo with the torque on and the watchdog set that hears nothing addressed to it
// for that long stops (goal velocity 0, goal position = present), sets the watchdog to -1 and refuses goal writes
// until it is cleared. It uses the driver's packet codec; the tests pin that codec to the e-Manual's vectors.
#pragma once

#include <array>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <mutex>
#include <set>
#include <thread>
#include <vector>

#include "packet.hpp"

namespace rcand::plugins::dynamixel::testing {

class ServoEmulator {
 public:
  using Clock = std::chrono::steady_clock;
  struct Servo {
    std::array<std::uint8_t, 1024> table{};
    bool present = true;
    Clock::time_point last_heard{};
    double position = 2048.0;  // ticks, fractional while moving
    std::uint64_t watchdog_trips = 0;
    Clock::time_point tripped_at{};
    std::uint64_t reboots = 0;

    std::uint8_t u8(std::uint16_t at) const { return table[at]; }
    std::int32_t i32(std::uint16_t at) const { return get_i32(table, at); }
    void set_i32(std::uint16_t at, std::int32_t value);
  };
  struct Received {
    Clock::time_point at;
    Packet packet;
  };

  // `master`: the pty master (non-blocking). `model`: the model number every servo reports (1020, XM430-W350).
  ServoEmulator(int master, std::vector<std::uint8_t> ids, std::uint16_t model = 1020);
  ~ServoEmulator();
  ServoEmulator(const ServoEmulator&) = delete;
  ServoEmulator& operator=(const ServoEmulator&) = delete;

  // ---- test controls (any thread) ----------------------------------------------------------------------------
  void set_present(std::uint8_t id, bool present);
  void set_hardware_error(std::uint8_t id, std::uint8_t bits);  // latches; a reboot clears it
  void set_position(std::uint8_t id, std::int32_t ticks);
  // The servo's next reply is late: sent only after the next instruction packet arrives, ahead of its answers
  // (what a bus sees when a host gave up waiting and asked again).
  void hold_next_reply(std::uint8_t id);
  // Delay each reply by its wire time at this rate (0: reply at once), so timing looks like a real 1 Mbps bus.
  void set_wire_baud(int baud);

  Servo servo(std::uint8_t id) const;
  std::vector<Received> received() const;
  void clear_received();
  // Waits until `predicate` (called under the emulator's lock with the servos; it must not call back into the
  // emulator) holds, or `timeout`. No polling:
  // the emulator notifies after every packet and every motion tick.
  bool wait_until(const std::function<bool(const std::map<std::uint8_t, Servo>&)>& predicate, std::chrono::milliseconds timeout);
  // The same for the instruction packets received so far (the predicate must not call back into the emulator).
  bool wait_for_packets(const std::function<bool(const std::vector<Received>&)>& predicate, std::chrono::milliseconds timeout);

 private:
  void loop();
  void handle(const Packet& packet, Clock::time_point now);  // requires mutex_
  void reply(std::uint8_t id, std::uint8_t error, std::span<const std::uint8_t> params);
  void tick(Clock::time_point now);  // requires mutex_: motion and watchdogs
  void reset(Servo& servo, std::uint8_t id);

  const int master_;
  const std::uint16_t model_;
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  std::map<std::uint8_t, Servo> servos_;
  std::vector<Received> received_;
  std::vector<std::uint8_t> outbox_;
  std::set<std::uint8_t> hold_next_;
  std::vector<std::uint8_t> held_;  // replies held back by hold_next_reply()
  int wire_baud_ = 0;
  Clock::time_point last_tick_;
  Decoder decoder_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

}  // namespace rcand::plugins::dynamixel::testing
