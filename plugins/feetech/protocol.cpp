#include "protocol.hpp"

#include <algorithm>
#include <cstdlib>
#include <string_view>

namespace rcand::plugins::feetech {

std::string_view first_status_text(std::uint8_t error) noexcept {
  if (error & status_bit::kVoltage) return "input voltage out of range";
  if (error & status_bit::kAngle) return "angle out of range";
  if (error & status_bit::kOverheat) return "overheated";
  if (error & status_bit::kOverEle) return "over current";
  if (error & status_bit::kOverload) return "overloaded";
  return error ? "unknown error" : "";
}

std::uint8_t checksum(std::span<const std::uint8_t> id_to_last_param) noexcept {
  unsigned sum = 0;
  for (const auto b : id_to_last_param) sum += b;
  return static_cast<std::uint8_t>(~sum & 0xFF);
}

std::vector<std::uint8_t> encode(std::uint8_t id, std::uint8_t code, std::span<const std::uint8_t> params) {
  std::vector<std::uint8_t> out{0xFF, 0xFF, id, static_cast<std::uint8_t>(params.size() + 2), code};
  out.insert(out.end(), params.begin(), params.end());
  out.push_back(checksum(std::span(out).subspan(2)));
  return out;
}

void Decoder::feed(std::span<const std::uint8_t> bytes) { buffer_.insert(buffer_.end(), bytes.begin(), bytes.end()); }

std::optional<Packet> Decoder::next() {
  for (;;) {
    // Find FF FF followed by an id that is not FF (a run of FF is preamble).
    std::size_t start = 0;
    while (start + 2 < buffer_.size() && !(buffer_[start] == 0xFF && buffer_[start + 1] == 0xFF && buffer_[start + 2] != 0xFF))
      ++start;
    if (start + 2 >= buffer_.size()) {
      // Keep a possible header's first bytes for the next feed.
      const std::size_t keep = std::min<std::size_t>(buffer_.size(), 2);
      buffer_.erase(buffer_.begin(), buffer_.end() - static_cast<std::ptrdiff_t>(keep));
      return std::nullopt;
    }
    buffer_.erase(buffer_.begin(), buffer_.begin() + static_cast<std::ptrdiff_t>(start));
    if (buffer_.size() < 4) return std::nullopt;
    const std::size_t length = buffer_[3];
    if (length < 2) {  // no room for the code and the checksum: not a header
      ++dropped_;
      buffer_.erase(buffer_.begin());
      continue;
    }
    const std::size_t total = 4 + length;
    if (buffer_.size() < total) return std::nullopt;
    const auto frame = std::span(buffer_).first(total);
    if (checksum(frame.subspan(2, total - 3)) != frame[total - 1]) {
      ++dropped_;
      buffer_.erase(buffer_.begin());
      continue;
    }
    Packet packet{frame[2], frame[4], std::vector<std::uint8_t>(frame.begin() + 5, frame.end() - 1)};
    buffer_.erase(buffer_.begin(), buffer_.begin() + static_cast<std::ptrdiff_t>(total));
    return packet;
  }
}

std::uint16_t encode_sign_magnitude(std::int32_t value, int sign_bit) noexcept {
  const std::int32_t max = (1 << sign_bit) - 1;
  const std::int32_t magnitude = std::min(std::abs(value), max);
  return static_cast<std::uint16_t>((value < 0 ? 1 << sign_bit : 0) | magnitude);
}

std::int32_t decode_sign_magnitude(std::uint16_t raw, int sign_bit) noexcept {
  const std::int32_t magnitude = raw & ((1 << sign_bit) - 1);
  return (raw >> sign_bit) & 1 ? -magnitude : magnitude;
}

}  // namespace rcand::plugins::feetech
