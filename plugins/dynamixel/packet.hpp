// Dynamixel Protocol 2.0 framing (ROBOTIS e-Manual, "Protocol 2.0"): FF FF FD 00 | ID | LEN_L LEN_H | INST | params |
// CRC_L CRC_H. LEN counts everything after itself (instruction, stuffed params, CRC). Inside instruction+params, every
// FF FF FD is sent as FF FF FD FD so that a header never appears in a body; the CRC covers the stuffed packet.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

namespace rcand::plugins::dynamixel {

inline constexpr std::uint8_t kBroadcastId = 0xFE;
inline constexpr std::uint8_t kMaxId = 252;  // 253..255 are reserved, 254 is broadcast

namespace inst {
inline constexpr std::uint8_t kPing = 0x01;
inline constexpr std::uint8_t kRead = 0x02;
inline constexpr std::uint8_t kWrite = 0x03;
inline constexpr std::uint8_t kReboot = 0x08;
inline constexpr std::uint8_t kStatus = 0x55;
inline constexpr std::uint8_t kSyncRead = 0x82;
inline constexpr std::uint8_t kSyncWrite = 0x83;
}  // namespace inst

// CRC-16 with polynomial 0x8005, initial value 0, not reflected (the catalogue's CRC-16/BUYPASS): the protocol's CRC.
std::uint16_t crc16(std::span<const std::uint8_t> bytes, std::uint16_t crc = 0) noexcept;

// FF FF FD -> FF FF FD FD, and back.
std::vector<std::uint8_t> stuff(std::span<const std::uint8_t> body);
std::vector<std::uint8_t> unstuff(std::span<const std::uint8_t> body);

// A whole packet on the wire. For an instruction `code` is the instruction; for a status packet it is 0x55 and
// params[0] is the error byte.
std::vector<std::uint8_t> encode(std::uint8_t id, std::uint8_t code, std::span<const std::uint8_t> params);

struct Packet {
  std::uint8_t id = 0;
  std::uint8_t code = 0;             // instruction, or kStatus
  std::vector<std::uint8_t> params;  // unstuffed; a status packet's error byte first
};

// Reassembles packets from a byte stream that may start mid-packet, split anywhere, or carry noise: it resynchronises
// on the header, and drops a packet whose CRC or length is wrong (counted, never returned).
class Decoder {
 public:
  static constexpr std::size_t kMaxLength = 1024;  // longer than any packet rcand sends or expects
  void feed(std::span<const std::uint8_t> bytes);
  std::optional<Packet> next();
  void clear() noexcept { buffer_.clear(); }
  std::size_t dropped() const noexcept { return dropped_; }

 private:
  std::vector<std::uint8_t> buffer_;
  std::size_t dropped_ = 0;
};

// Little-endian helpers for control-table values.
inline void put_u16(std::vector<std::uint8_t>& out, std::uint16_t v) {
  out.push_back(static_cast<std::uint8_t>(v & 0xFF));
  out.push_back(static_cast<std::uint8_t>(v >> 8));
}
inline void put_u32(std::vector<std::uint8_t>& out, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
}
inline std::uint16_t get_u16(std::span<const std::uint8_t> b, std::size_t at) {
  return static_cast<std::uint16_t>(b[at] | b[at + 1] << 8);
}
inline std::int32_t get_i32(std::span<const std::uint8_t> b, std::size_t at) {
  return static_cast<std::int32_t>(static_cast<std::uint32_t>(b[at]) | static_cast<std::uint32_t>(b[at + 1]) << 8 |
                                   static_cast<std::uint32_t>(b[at + 2]) << 16 | static_cast<std::uint32_t>(b[at + 3]) << 24);
}

}  // namespace rcand::plugins::dynamixel
