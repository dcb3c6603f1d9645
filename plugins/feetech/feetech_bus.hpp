// Feetech transactions on a serial line (the SerialLink of the Dynamixel plugin: termios tty, interruptible reads):
// one instruction out, its status packet(s) back, with a reply timeout of the wire time plus a margin. Not
// thread-safe: exactly one thread (the bus worker, rcand/sdk/bus_worker.hpp) owns a FeetechBus.
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "dynamixel/serial_link.hpp"
#include "protocol.hpp"

namespace rcand::plugins::feetech {

using dynamixel::Interrupted;
using dynamixel::SerialError;
using dynamixel::SerialLink;

class FeetechError : public std::runtime_error {
 public:
  enum class Kind {
    NoReply,   // the servo did not answer in time (after the retries): power, ID, baud rate, cabling
    BadReply,  // an answer of the wrong shape
  };
  FeetechError(Kind kind, std::uint8_t id, const std::string& message) : std::runtime_error(message), kind_(kind), id_(id) {}
  Kind kind() const noexcept { return kind_; }
  std::uint8_t id() const noexcept { return id_; }

 private:
  Kind kind_;
  std::uint8_t id_;
};

struct SyncReadResult {
  std::vector<std::optional<std::vector<std::uint8_t>>> data;  // per requested id, nullopt when it did not answer
  std::vector<std::pair<std::uint8_t, std::uint8_t>> errors;   // (id, status error byte) of replies with one set
};

using SyncItems = std::vector<std::pair<std::uint8_t, std::vector<std::uint8_t>>>;

class FeetechBus {
 public:
  // `reply_margin`: added to the wire time of every expected reply (USB latency timer, return delay, scheduling).
  // `retries`: a read, write or ping that gets no answer is sent again this many times before NoReply.
  FeetechBus(std::shared_ptr<SerialLink> link, std::chrono::microseconds reply_margin, unsigned retries = 2);

  // The servo's error byte (0: fine). Throws FeetechError.
  std::uint8_t ping(std::uint8_t id);
  std::vector<std::uint8_t> read(std::uint8_t id, std::uint8_t address, std::uint8_t length, std::uint8_t* error = nullptr);
  void write(std::uint8_t id, std::uint8_t address, std::span<const std::uint8_t> data);
  // One broadcast packet, no reply: every (id, data) pair gets `data` (all `length` bytes) at `address`.
  void sync_write(std::uint8_t address, std::uint8_t length, const SyncItems& items);
  // One packet out; the servos answer one after another. A missing servo is nullopt, never an exception.
  SyncReadResult sync_read(std::uint8_t address, std::uint8_t length, const std::vector<std::uint8_t>& ids);

  SerialLink& link() noexcept { return *link_; }
  // For the bus worker (rcand::sdk::InterruptibleBus): halt cuts a read waiting for a late reply short.
  using Interrupted = dynamixel::Interrupted;
  void interrupt() noexcept { link_->interrupt(); }
  void clear_interrupt() noexcept { link_->clear_interrupt(); }
  std::size_t corrupt_packets() const noexcept { return decoder_.dropped(); }

 private:
  void send(std::span<const std::uint8_t> packet);
  std::optional<Packet> receive(std::uint8_t id, SerialLink::Clock::time_point until);
  // Sends `packet` until `id` answers with `reply_params` bytes (1 + retries tries).
  Packet transact(std::uint8_t id, const std::vector<std::uint8_t>& packet, std::size_t reply_params, const char* what);
  SerialLink::Clock::time_point deadline_for(std::size_t reply_bytes) const;

  std::shared_ptr<SerialLink> link_;
  std::chrono::microseconds margin_;
  unsigned retries_;
  Decoder decoder_;
};

}  // namespace rcand::plugins::feetech
