// Protocol 2.0 transactions on a SerialLink: one instruction out, its status packet(s) back, with a reply timeout
// of the wire time plus a margin (the USB adapter's latency timer lives in that margin). Not thread-safe: exactly
// one thread (the bus worker, rcand/sdk/bus_worker.hpp) owns a DxlBus.
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <stdexcept>
#include <utility>
#include <vector>

#include "packet.hpp"
#include "serial_link.hpp"

namespace rcand::plugins::dynamixel {

class DxlError : public std::runtime_error {
 public:
  enum class Kind {
    NoReply,     // the servo did not answer in time: power, ID, baud rate, cabling
    ServoError,  // it answered with an error (the e-Manual's error numbers 1..7)
    BadReply,    // an answer of the wrong shape
  };
  DxlError(Kind kind, std::uint8_t id, const std::string& message) : std::runtime_error(message), kind_(kind), id_(id) {}
  Kind kind() const noexcept { return kind_; }
  std::uint8_t id() const noexcept { return id_; }

 private:
  Kind kind_;
  std::uint8_t id_;
};

// The status packet's error byte: bit 7 is the Alert (a hardware error is latched: read Hardware Error Status),
// bits 0..6 the error number of this instruction.
inline constexpr std::uint8_t kAlertBit = 0x80;
const char* error_number_text(std::uint8_t number);

struct PingReply {
  std::uint8_t id;
  std::uint16_t model;
  std::uint8_t firmware;
  bool alert;
};

struct SyncReadResult {
  std::vector<std::optional<std::vector<std::uint8_t>>> data;  // per requested id, nullopt when it did not answer
  std::vector<std::uint8_t> alerted;                           // ids whose reply carried the Alert bit
};

class DxlBus {
 public:
  // `reply_margin`: added to the wire time of every expected reply (latency timer, return delay, scheduling).
  DxlBus(std::shared_ptr<SerialLink> link, std::chrono::microseconds reply_margin);

  // `tries` > 1: a reply lost to noise, or late on a loaded host, is asked for again before the servo counts as
  // missing (a ping changes nothing, so repeating it is safe).
  PingReply ping(std::uint8_t id, unsigned tries = 1);
  // A broadcast ping: every servo on the bus answers, in ID order; each ID is listed once.
  std::vector<PingReply> scan();
  // Throws DxlError (NoReply, ServoError, BadReply). `alert` (optional) is set from the reply's Alert bit.
  std::vector<std::uint8_t> read(std::uint8_t id, std::uint16_t address, std::uint16_t length, bool* alert = nullptr);
  void write(std::uint8_t id, std::uint16_t address, std::span<const std::uint8_t> data, bool* alert = nullptr);
  void reboot(std::uint8_t id);
  // One broadcast packet, no reply: every (id, data) pair gets `data` (all the same length) at `address`.
  void sync_write(std::uint16_t address, std::uint16_t length,
                  const std::vector<std::pair<std::uint8_t, std::vector<std::uint8_t>>>& items);
  // One packet out; the servos answer one after another. Missing servos are nullopt, never an exception.
  SyncReadResult sync_read(std::uint16_t address, std::uint16_t length, const std::vector<std::uint8_t>& ids);

  SerialLink& link() noexcept { return *link_; }
  // For the bus worker (rcand::sdk::InterruptibleBus): halt cuts a read waiting for a late reply short.
  using Interrupted = dynamixel::Interrupted;
  void interrupt() noexcept { link_->interrupt(); }
  void clear_interrupt() noexcept { link_->clear_interrupt(); }
  std::size_t corrupt_packets() const noexcept { return decoder_.dropped(); }

 private:
  void send(std::span<const std::uint8_t> packet);
  // The next status packet from `id` (any id for kBroadcastId) before `until`, or nullopt.
  std::optional<Packet> receive(std::uint8_t id, SerialLink::Clock::time_point until);
  Packet expect(std::uint8_t id, std::size_t reply_params, const char* what);
  SerialLink::Clock::time_point deadline_for(std::size_t reply_bytes) const;

  std::shared_ptr<SerialLink> link_;
  std::chrono::microseconds margin_;
  Decoder decoder_;
};

}  // namespace rcand::plugins::dynamixel
