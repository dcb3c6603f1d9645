#include "pca9685_registers.hpp"

#include <algorithm>
#include <cmath>

namespace rcand::plugins::pca9685 {

std::optional<int> prescale_for(double frequency_hz, double oscillator_hz) {
  if (!std::isfinite(frequency_hz) || !std::isfinite(oscillator_hz) || frequency_hz <= 0.0 || oscillator_hz <= 0.0)
    return std::nullopt;
  const double value = std::round(oscillator_hz / (4096.0 * frequency_hz)) - 1.0;
  if (value < kMinPrescale || value > kMaxPrescale) return std::nullopt;
  return static_cast<int>(value);
}

double frequency_of(int prescale, double oscillator_hz) { return oscillator_hz / (4096.0 * (prescale + 1)); }

ChannelCounts ChannelCounts::duty(double duty) {
  if (!(duty > 0.0)) return full_off();  // also NaN
  if (duty >= 1.0) return full_on();
  const auto counts = static_cast<std::uint16_t>(std::clamp(std::lround(duty * 4096.0), 1L, 4095L));
  return {0, counts};
}

ChannelCounts ChannelCounts::pulse(double width_us, int prescale, double oscillator_hz) {
  if (!(width_us > 0.0)) return full_off();
  // One count lasts (prescale + 1) / osc seconds.
  const long counts = std::lround(width_us * 1e-6 * oscillator_hz / (prescale + 1));
  if (counts >= 4096) return full_on();
  return {0, static_cast<std::uint16_t>(std::max(1L, counts))};
}

std::vector<std::uint8_t> channel_block(const ChannelTable& table, int first, int last) {
  std::vector<std::uint8_t> bytes{static_cast<std::uint8_t>(reg::kLed0OnL + 4 * first)};
  for (int ch = first; ch <= last; ++ch) {
    const ChannelCounts& c = table[static_cast<std::size_t>(ch)];
    bytes.insert(bytes.end(), {static_cast<std::uint8_t>(c.on & 0xFF), static_cast<std::uint8_t>(c.on >> 8),
                               static_cast<std::uint8_t>(c.off & 0xFF), static_cast<std::uint8_t>(c.off >> 8)});
  }
  return bytes;
}

std::vector<std::uint8_t> all_off_block() { return {reg::kAllLedOnL, 0x00, 0x00, 0x00, reg::kFullBit}; }

std::vector<std::vector<std::uint8_t>> wake_sequence(int prescale) {
  // Auto-increment is set first (power-on MODE1 has it clear), so the 4-byte ALL_LED write lands in 4 registers.
  return {{reg::kMode1, static_cast<std::uint8_t>(reg::kMode1Sleep | reg::kMode1Ai)},
          all_off_block(),
          {reg::kMode2, reg::kMode2Outdrv},
          {reg::kPreScale, static_cast<std::uint8_t>(prescale)},
          {reg::kMode1, reg::kMode1Ai}};
}

std::vector<std::uint8_t> restart_block() { return {reg::kMode1, static_cast<std::uint8_t>(reg::kMode1Restart | reg::kMode1Ai)}; }

}  // namespace rcand::plugins::pca9685
