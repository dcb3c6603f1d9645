// Feetech serial bus servo framing (the SCS/STS/SMS protocol of Feetech's SCServo SDK, SCS.cpp / INST.h of SCServo_Linux,
// and of LeRobot's src/lerobot/motors/feetech/feetech.py): FF FF | ID | LEN | INST-or-ERROR | params | CHECKSUM.
// LEN counts the params plus 2 (the instruction/error byte and the checksum); CHECKSUM = ~(ID + LEN + INST + params)
// & 0xFF. Instruction and status packets share the frame: a status packet carries the servo's error byte where an
// instruction packet carries the instruction. No byte stuffing: the decoder resynchronises on a bad checksum.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

namespace rcand::plugins::feetech {

inline constexpr std::uint8_t kBroadcastId = 0xFE;
inline constexpr std::uint8_t kMaxId = 253;  // 254 is broadcast

namespace inst {
inline constexpr std::uint8_t kPing = 0x01;
inline constexpr std::uint8_t kRead = 0x02;
inline constexpr std::uint8_t kWrite = 0x03;
inline constexpr std::uint8_t kRegWrite = 0x04;
inline constexpr std::uint8_t kAction = 0x05;
inline constexpr std::uint8_t kSyncRead = 0x82;
inline constexpr std::uint8_t kSyncWrite = 0x83;
}  // namespace inst

// The status packet's error byte (SCServo SDK, protocol_packet_handler.py getRxPacketError): one bit per condition.
namespace status_bit {
inline constexpr std::uint8_t kVoltage = 0x01;
inline constexpr std::uint8_t kAngle = 0x02;
inline constexpr std::uint8_t kOverheat = 0x04;
inline constexpr std::uint8_t kOverEle = 0x08;  // over current
inline constexpr std::uint8_t kOverload = 0x20;
}  // namespace status_bit
// "input voltage, overheat" for the set bits; "" for 0.
std::string_view first_status_text(std::uint8_t error) noexcept;

// ~(sum of id, length, instruction/error and params) & 0xFF.
std::uint8_t checksum(std::span<const std::uint8_t> id_to_last_param) noexcept;

// A whole packet on the wire. `code` is the instruction (or, from a servo, the error byte).
std::vector<std::uint8_t> encode(std::uint8_t id, std::uint8_t code, std::span<const std::uint8_t> params);

struct Packet {
  std::uint8_t id = 0;
  std::uint8_t code = 0;  // instruction, or the status packet's error byte
  std::vector<std::uint8_t> params;
};

// Reassembles packets from a byte stream that may start mid-packet, be split anywhere or carry noise: it looks for
// FF FF, takes the frame LEN announces, and drops it (counted, one byte skipped, resynchronising) if the checksum
// is wrong.
class Decoder {
 public:
  void feed(std::span<const std::uint8_t> bytes);
  std::optional<Packet> next();
  void clear() noexcept { buffer_.clear(); }
  std::size_t dropped() const noexcept { return dropped_; }

 private:
  std::vector<std::uint8_t> buffer_;
  std::size_t dropped_ = 0;
};

// Two-byte control-table values. STS/SMS (protocol 0) are little-endian; SCS (protocol 1) big-endian.
enum class Endian { Little, Big };
inline void put_u16(std::vector<std::uint8_t>& out, std::uint16_t v, Endian e = Endian::Little) {
  const auto lo = static_cast<std::uint8_t>(v & 0xFF), hi = static_cast<std::uint8_t>(v >> 8);
  if (e == Endian::Little) {
    out.push_back(lo);
    out.push_back(hi);
  } else {
    out.push_back(hi);
    out.push_back(lo);
  }
}
inline std::uint16_t get_u16(std::span<const std::uint8_t> b, std::size_t at, Endian e = Endian::Little) {
  return e == Endian::Little ? static_cast<std::uint16_t>(b[at] | b[at + 1] << 8)
                             : static_cast<std::uint16_t>(b[at] << 8 | b[at + 1]);
}

// Sign-magnitude with the sign at `sign_bit` (STS: bit 15 for positions and speeds, bit 10 for the load; lerobot's
// tables.py STS_SMS_SERIES_ENCODINGS_TABLE and encoding_utils.py). The magnitude saturates at its largest value.
std::uint16_t encode_sign_magnitude(std::int32_t value, int sign_bit) noexcept;
std::int32_t decode_sign_magnitude(std::uint16_t raw, int sign_bit) noexcept;

}  // namespace rcand::plugins::feetech
