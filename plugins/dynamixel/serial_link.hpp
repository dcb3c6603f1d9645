// The serial line as the Dynamixel bus needs it: whole-packet writes, reads that wait up to a time point, and an
// interrupt any thread can raise to cut a wait short (halt must not sit behind a poll waiting for a late reply).
// The real backend is a termios tty (posix_serial.hpp); tests run it on a pseudo-terminal with a servo emulator.
#pragma once

#include <chrono>
#include <cstdint>
#include <span>
#include <stdexcept>
#include <string>

#include <rcand/sdk/device_fault.hpp>

namespace rcand::plugins::dynamixel {

// A device fault (rcand/sdk/device_fault.hpp): opening the port names the path, the OS error and a hint.
class SerialError : public sdk::DeviceFault {
 public:
  using sdk::DeviceFault::DeviceFault;
};
// A wait cut short by interrupt(): the transaction is abandoned, not failed.
class Interrupted : public std::runtime_error {
 public:
  Interrupted() : std::runtime_error("interrupted by a halt") {}
};

class SerialLink {
 public:
  using Clock = std::chrono::steady_clock;
  virtual ~SerialLink() = default;
  // Writes every byte or throws SerialError (also when `until` passes first). Never interrupted: a packet cut in
  // half would make the servos swallow the next one too.
  virtual void write(std::span<const std::uint8_t> bytes, Clock::time_point until) = 0;
  // Waits until at least one byte arrives (returns how many were read), `until` passes (returns 0), or interrupt()
  // was raised (throws Interrupted). Throws SerialError on an I/O error.
  virtual std::size_t read_some(std::span<std::uint8_t> out, Clock::time_point until) = 0;
  // Drops whatever arrived and was not read (late replies of an abandoned transaction).
  virtual void discard_input() = 0;
  // Any thread: the current or next read_some throws Interrupted until clear_interrupt().
  virtual void interrupt() noexcept = 0;
  virtual void clear_interrupt() noexcept = 0;
  virtual std::string path() const = 0;
  virtual int baud_rate() const = 0;
};

}  // namespace rcand::plugins::dynamixel
