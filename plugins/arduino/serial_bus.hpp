// The Arduino's USB serial port as the BusWorker's bus (sdk::InterruptibleBus): raw 8N1 termios, no flow control,
// non-blocking I/O with poll(), and an eventfd so that halt() cuts short a wait for a reply (a sensor read can keep
// the board busy for 30 ms). Opening the port raises DTR, which resets an Uno or Nano: its bootloader runs for about
// 2 s before the sketch answers (the driver's start() pings until it does).
#pragma once

#include <rcand/sdk/device_fault.hpp>

#include <chrono>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>

#include "protocol.hpp"

namespace rcand::plugins::arduino {

class SerialFault : public sdk::DeviceFault {
 public:
  using sdk::DeviceFault::DeviceFault;
};

class ArduinoBus {
 public:
  using Clock = std::chrono::steady_clock;
  // A wait cut short by interrupt(): the transaction is abandoned, not failed.
  class Interrupted : public std::runtime_error {
   public:
    Interrupted() : std::runtime_error("interrupted by a halt") {}
  };
  enum class Expect { Ack, Sensor };

  // Throws SerialFault naming the path: missing device, permission (the dialout group), not a tty, a rate termios
  // cannot set.
  ArduinoBus(std::string path, int baud);
  ~ArduinoBus();
  ArduinoBus(const ArduinoBus&) = delete;
  ArduinoBus& operator=(const ArduinoBus&) = delete;

  // Writes the whole line or throws SerialFault (also when `until` passes first: the port accepts nothing). Never
  // interrupted: half a line would corrupt the next one too. Its reply, if any, is left unread (the next transaction
  // drops it).
  void send(std::string_view line, Clock::time_point until);
  // Sends `line`, then reads lines until the reply it expects: an ack or an error for a command, a sensor reply (or
  // an error) for a sensor query; other lines (a late ack of an abandoned transaction) are skipped. nullopt: no such
  // reply by `until`. Throws Interrupted, or SerialFault on an I/O error.
  std::optional<Reply> transact(std::string_view line, Expect expect, Clock::time_point until);
  // Drops what arrived and was not read (replies of a transaction that was abandoned).
  void discard_input();
  // Any thread: the current or next wait for a reply throws Interrupted until clear_interrupt().
  void interrupt() noexcept;
  void clear_interrupt() noexcept;

  const std::string& path() const noexcept { return path_; }
  int baud() const noexcept { return baud_; }
  std::uint64_t skipped_lines() const noexcept { return skipped_; }

 private:
  std::optional<std::string> read_line(Clock::time_point until);

  const std::string path_;
  const int baud_;
  int fd_ = -1;
  int wake_ = -1;
  LineSplitter splitter_;
  bool out_of_step_ = false;  // a reply may still be on its way: drop input before the next command
  std::uint64_t skipped_ = 0;
};

}  // namespace rcand::plugins::arduino
