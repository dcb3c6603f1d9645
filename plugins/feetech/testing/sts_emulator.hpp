// STS servos (STS3215 by default) on the master side of a pseudo-terminal, for tests and benchmarks: a 256-byte
// control table per servo (EEPROM, addresses below 40, writable only while Lock (55) is 0), ping, read, write,
// REG WRITE + ACTION, sync read, sync write, and motion: position mode travels toward the goal position at the goal
// speed (0: full speed), wheel mode turns at the goal speed (sign-magnitude, bit 15), nothing moves with the torque
// off. Like the real servos it has no bus watchdog: a servo keeps its last goal however long the bus is silent.
// It uses the driver's packet codec; the tests pin that codec to vectors derived by hand.
#pragma once

#include <array>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <mutex>
#include <thread>
#include <vector>

#include "protocol.hpp"

namespace rcand::plugins::feetech::testing {

class StsEmulator {
 public:
  using Clock = std::chrono::steady_clock;
  struct Servo {
    std::array<std::uint8_t, 256> table{};
    std::array<std::uint8_t, 256> registered{};                  // REG WRITE's pending bytes, applied by ACTION
    std::vector<std::pair<std::uint8_t, std::uint8_t>> pending;  // (address, length) of a REG WRITE
    bool present = true;
    double position = 2048.0;  // ticks, fractional while moving
    std::uint64_t eeprom_refused = 0;

    std::uint8_t u8(std::uint8_t at) const { return table[at]; }
    std::uint16_t u16(std::uint8_t at) const { return get_u16(table, at); }
    std::int32_t signed16(std::uint8_t at) const { return decode_sign_magnitude(get_u16(table, at), 15); }
  };
  struct Received {
    Clock::time_point at;
    Packet packet;
  };

  // `master`: the pty master (non-blocking). `model`: the model number every servo reports (777, STS3215).
  StsEmulator(int master, std::vector<std::uint8_t> ids, std::uint16_t model = 777);
  ~StsEmulator();
  StsEmulator(const StsEmulator&) = delete;
  StsEmulator& operator=(const StsEmulator&) = delete;

  // ---- test controls (any thread) ----------------------------------------------------------------------------
  void set_present(std::uint8_t id, bool present);
  void set_position(std::uint8_t id, std::int32_t ticks);
  void set_angle_limits(std::uint8_t id, std::uint16_t min_ticks, std::uint16_t max_ticks);
  void set_operating_mode(std::uint8_t id, std::uint8_t mode);
  void set_status_error(std::uint8_t id, std::uint8_t bits);  // the error byte of every reply
  // Delay each reply by its wire time at this rate (0: reply at once), so timing looks like a real 1 Mbps bus.
  void set_wire_baud(int baud);

  Servo servo(std::uint8_t id) const;
  std::vector<Received> received() const;
  void clear_received();
  // Waits until `predicate` (called under the emulator's lock; it must not call back into the emulator) holds, or
  // `timeout`. No polling: the emulator notifies after every packet and every motion tick.
  bool wait_until(const std::function<bool(const std::map<std::uint8_t, Servo>&)>& predicate, std::chrono::milliseconds timeout);
  bool wait_for_packets(const std::function<bool(const std::vector<Received>&)>& predicate, std::chrono::milliseconds timeout);

 private:
  void loop();
  void handle(const Packet& packet, Clock::time_point now);  // requires mutex_
  void reply(std::uint8_t id, std::span<const std::uint8_t> params);
  void tick(Clock::time_point now);  // requires mutex_: motion
  std::uint8_t store(Servo& servo, std::uint8_t at, std::span<const std::uint8_t> data);

  const int master_;
  const std::uint16_t model_;
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  std::map<std::uint8_t, Servo> servos_;
  std::map<std::uint8_t, std::uint8_t> status_errors_;
  std::vector<Received> received_;
  std::vector<std::uint8_t> outbox_;
  int wire_baud_ = 0;
  Clock::time_point last_tick_;
  Decoder decoder_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

}  // namespace rcand::plugins::feetech::testing
