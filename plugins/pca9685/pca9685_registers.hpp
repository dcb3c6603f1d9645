// The PCA9685 register map and the arithmetic of its datasheet (NXP PCA9685 rev. 4): the prescale, the 12-bit
// ON/OFF counts of a channel, and the byte blocks the driver writes. Pure, so every vector is tested alone.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <vector>

namespace rcand::plugins::pca9685 {

namespace reg {
inline constexpr std::uint8_t kMode1 = 0x00;
inline constexpr std::uint8_t kMode2 = 0x01;
inline constexpr std::uint8_t kLed0OnL = 0x06;  // channel n: 0x06 + 4n .. 0x09 + 4n (ON_L, ON_H, OFF_L, OFF_H)
inline constexpr std::uint8_t kAllLedOnL = 0xFA;
inline constexpr std::uint8_t kPreScale = 0xFE;

inline constexpr std::uint8_t kMode1Restart = 0x80;
inline constexpr std::uint8_t kMode1Ai = 0x20;  // register auto-increment: a block write fills consecutive registers
inline constexpr std::uint8_t kMode1Sleep = 0x10;
// Totem-pole outputs (what motor and servo boards wire). OCH stays 0: outputs change on the I2C STOP, so every
// channel of one block write changes at the same instant (a bridge's two inputs never pass through "both on").
inline constexpr std::uint8_t kMode2Outdrv = 0x04;
inline constexpr std::uint8_t kFullBit = 0x10;  // bit 4 of ON_H (full on) or OFF_H (full off)
}  // namespace reg

inline constexpr int kChannels = 16;
inline constexpr double kInternalOscillatorHz = 25'000'000.0;
inline constexpr int kMinPrescale = 3;  // datasheet: PRE_SCALE below 03h is clamped by the chip to 03h
inline constexpr int kMaxPrescale = 255;

// PRE_SCALE = round(osc / (4096 * f)) - 1 (datasheet 7.3.5), or nullopt when f needs a value outside [3, 255].
std::optional<int> prescale_for(double frequency_hz, double oscillator_hz = kInternalOscillatorHz);
// The output frequency a prescale really gives.
double frequency_of(int prescale, double oscillator_hz = kInternalOscillatorHz);

// One channel's four registers. Full off wins over full on in the chip; we never set both.
struct ChannelCounts {
  std::uint16_t on = 0;  // 12-bit count at which the output goes high, or kFullBit in the high byte
  std::uint16_t off = 0;
  static ChannelCounts full_off() { return {0, static_cast<std::uint16_t>(reg::kFullBit << 8)}; }
  static ChannelCounts full_on() { return {static_cast<std::uint16_t>(reg::kFullBit << 8), 0}; }
  // Duty in [0, 1]: 0 is full off, 1 full on, otherwise high for round(duty * 4096) counts from 0.
  static ChannelCounts duty(double duty);
  // A pulse of `width_us` every period of `prescale` (servos, ESCs).
  static ChannelCounts pulse(double width_us, int prescale, double oscillator_hz);
  bool operator==(const ChannelCounts&) const = default;
};
using ChannelTable = std::array<ChannelCounts, kChannels>;

// [LEDn_ON_L, the 4 registers of channels first..last]: one auto-increment write.
std::vector<std::uint8_t> channel_block(const ChannelTable& table, int first, int last);
// [ALL_LED_ON_L, 4 registers]: every channel full off in one 5-byte write.
std::vector<std::uint8_t> all_off_block();

// The wake-up of datasheet 7.3.1.1 and 7.3.5 as separate writes, in order: MODE1 asleep with auto-increment
// (PRE_SCALE is writable only asleep), every output full off, MODE2 totem pole, PRE_SCALE, MODE1 awake; then, after
// the 500 us the oscillator needs, restart_block().
std::vector<std::vector<std::uint8_t>> wake_sequence(int prescale);
std::vector<std::uint8_t> restart_block();

}  // namespace rcand::plugins::pca9685
