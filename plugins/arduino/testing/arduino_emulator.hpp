// The reference runtime's bridge firmware (firmware/arduino_l298n_bridge.ino) on the master side of a
// pseudo-terminal, for tests and the benchmark: JSON lines in, {"ack":true} / {"sensor":...} / {"error":...} out,
// drive clamped to -255..255, the servo command, the HC-SR04 as a distance the test sets (-1: no echo), and the
// watchdog: when no non-empty line came for 1 s the motors stop. Opening the port resets the board (DTR): for
// boot_delay it reads nothing (the bootloader), then the sketch starts with the motors stopped. hung: the board
// stops reading and answering (a wedged USB link); its watchdog still runs.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "../protocol.hpp"  // not "protocol.hpp": a test may also have another plugin's folder (feetech) on its include path

namespace rcand::plugins::arduino::testing {

class ArduinoEmulator {
 public:
  using Clock = std::chrono::steady_clock;
  struct Board {
    int left = 0, right = 0;  // PWM in force
    bool port_open = false;
    bool booting = false;
    std::uint64_t boots = 0;           // resets by the port being opened
    std::uint64_t watchdog_stops = 0;  // the motors were running and the watchdog stopped them
    Clock::time_point watchdog_stopped_at{};
    int servo_pin = -1, servo_angle = -1;
    bool moving() const noexcept { return left != 0 || right != 0; }
  };
  struct Line {
    Clock::time_point at;
    std::string text;
  };

  ArduinoEmulator(int master, std::chrono::milliseconds boot_delay = std::chrono::milliseconds(0));
  ~ArduinoEmulator();
  ArduinoEmulator(const ArduinoEmulator&) = delete;
  ArduinoEmulator& operator=(const ArduinoEmulator&) = delete;

  // ---- test controls (any thread) ----
  void set_distance_mm(std::int64_t mm);
  void set_hung(bool hung);
  void set_silent(bool silent);  // reads but never answers (another sketch, or none)

  Board board() const;
  std::vector<Line> received() const;  // every line the sketch read, in order
  void clear_received();
  // Waits until `predicate` (called under the emulator's lock; it must not call back into it) holds, or `timeout`.
  // The emulator notifies after every line and every change of the motors.
  bool wait_until(const std::function<bool(const Board&, const std::vector<Line>&)>& predicate,
                  std::chrono::milliseconds timeout);

 private:
  void loop();
  void handle(const std::string& line, Clock::time_point now);  // requires mutex_
  void reply(const std::string& text);                          // requires mutex_

  const int master_;
  const std::chrono::milliseconds boot_delay_;
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  Board board_;
  std::vector<Line> received_;
  std::int64_t distance_mm_ = 1000;
  bool hung_ = false, silent_ = false;
  Clock::time_point last_line_{}, boot_until_{};
  std::string partial_;
  bool stop_ = false;
  std::thread thread_;
};

}  // namespace rcand::plugins::arduino::testing
