#include "packet.hpp"

#include <algorithm>
#include <array>

namespace rcand::plugins::dynamixel {

namespace {

constexpr std::array<std::uint8_t, 4> kHeader{0xFF, 0xFF, 0xFD, 0x00};
constexpr std::size_t kHeaderAndId = 5;  // header, id
constexpr std::size_t kBeforeBody = 7;   // header, id, length
constexpr std::size_t kMinLength = 3;    // instruction + CRC

// The table of the bitwise CRC below, built at compile time.
constexpr std::array<std::uint16_t, 256> make_table() {
  std::array<std::uint16_t, 256> table{};
  for (unsigned i = 0; i < 256; ++i) {
    std::uint16_t c = static_cast<std::uint16_t>(i << 8);
    for (int bit = 0; bit < 8; ++bit) c = static_cast<std::uint16_t>(c & 0x8000 ? (c << 1) ^ 0x8005 : c << 1);
    table[i] = c;
  }
  return table;
}
constexpr auto kTable = make_table();

// FF FF FD at `at` (the part of the header stuffing guards).
bool header_at(std::span<const std::uint8_t> b, std::size_t at) {
  return at + 3 <= b.size() && b[at] == 0xFF && b[at + 1] == 0xFF && b[at + 2] == 0xFD;
}

}  // namespace

std::uint16_t crc16(std::span<const std::uint8_t> bytes, std::uint16_t crc) noexcept {
  for (const auto byte : bytes) crc = static_cast<std::uint16_t>(crc << 8 ^ kTable[(crc >> 8 ^ byte) & 0xFF]);
  return crc;
}

std::vector<std::uint8_t> stuff(std::span<const std::uint8_t> body) {
  std::vector<std::uint8_t> out;
  out.reserve(body.size() + body.size() / 3);
  for (std::size_t i = 0; i < body.size(); ++i) {
    out.push_back(body[i]);
    if (i >= 2 && header_at(body, i - 2)) out.push_back(0xFD);
  }
  return out;
}

std::vector<std::uint8_t> unstuff(std::span<const std::uint8_t> body) {
  std::vector<std::uint8_t> out;
  out.reserve(body.size());
  for (std::size_t i = 0; i < body.size(); ++i) {
    out.push_back(body[i]);
    if (i >= 2 && header_at(body, i - 2) && i + 1 < body.size() && body[i + 1] == 0xFD) ++i;  // the stuffed FD
  }
  return out;
}

std::vector<std::uint8_t> encode(std::uint8_t id, std::uint8_t code, std::span<const std::uint8_t> params) {
  std::vector<std::uint8_t> body;
  body.reserve(params.size() + 1);
  body.push_back(code);
  body.insert(body.end(), params.begin(), params.end());
  const auto stuffed = stuff(body);
  const std::size_t length = stuffed.size() + 2;
  std::vector<std::uint8_t> packet(kHeader.begin(), kHeader.end());
  packet.reserve(kBeforeBody + length);
  packet.push_back(id);
  put_u16(packet, static_cast<std::uint16_t>(length));
  packet.insert(packet.end(), stuffed.begin(), stuffed.end());
  put_u16(packet, crc16(packet));
  return packet;
}

void Decoder::feed(std::span<const std::uint8_t> bytes) { buffer_.insert(buffer_.end(), bytes.begin(), bytes.end()); }

std::optional<Packet> Decoder::next() {
  for (;;) {
    // Drop everything before the first header, or before a header cut short at the end of what has arrived.
    std::size_t start = 0;
    for (; start < buffer_.size(); ++start) {
      const std::size_t n = std::min<std::size_t>(kHeader.size(), buffer_.size() - start);
      if (std::equal(kHeader.begin(), kHeader.begin() + static_cast<std::ptrdiff_t>(n),
                     buffer_.begin() + static_cast<std::ptrdiff_t>(start)))
        break;
    }
    buffer_.erase(buffer_.begin(), buffer_.begin() + static_cast<std::ptrdiff_t>(start));
    if (buffer_.size() < kBeforeBody) return std::nullopt;
    const std::size_t length = get_u16(buffer_, kHeaderAndId);
    const std::size_t total = kBeforeBody + length;
    if (length < kMinLength || length > kMaxLength) {
      ++dropped_;
      buffer_.erase(buffer_.begin());  // not a real header: look further
      continue;
    }
    if (buffer_.size() < total) return std::nullopt;
    if (crc16(std::span(buffer_).first(total - 2)) != get_u16(buffer_, total - 2)) {
      ++dropped_;
      buffer_.erase(buffer_.begin());
      continue;
    }
    const auto body = unstuff(std::span(buffer_).subspan(kBeforeBody, length - 2));
    Packet packet{buffer_[4], body[0], std::vector<std::uint8_t>(body.begin() + 1, body.end())};
    buffer_.erase(buffer_.begin(), buffer_.begin() + static_cast<std::ptrdiff_t>(total));
    return packet;
  }
}

}  // namespace rcand::plugins::dynamixel
