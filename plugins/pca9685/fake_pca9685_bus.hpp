// A PCA9685 on a fake I2C bus, for tests: the register map with the datasheet's auto-increment (0x00..0x45 then back
// to 0x00; 0xFA..0xFE then 0x00), ALL_LED writes loading every channel, PRE_SCALE writable only asleep, every
// transaction recorded. It can be absent (no ACK), fail on demand, or wedge (a transfer that blocks until released).
#pragma once

#include <array>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <optional>
#include <vector>

#include "i2c_bus.hpp"
#include "pca9685_registers.hpp"

namespace rcand::plugins::pca9685::testing {

class FakePca9685Bus final : public I2cBus {
 public:
  struct Transaction {
    bool read;
    std::uint8_t address;
    std::vector<std::uint8_t> bytes;  // written bytes (register first); for a read, the register only
  };

  explicit FakePca9685Bus(std::uint8_t address = 0x40) : address_(address) {
    regs_[reg::kMode1] = 0x11;  // power-on: SLEEP | ALLCALL, auto-increment off
    regs_[reg::kPreScale] = 0x1E;
    for (int ch = 0; ch < kChannels; ++ch) regs_[reg::kLed0OnL + 4 * ch + 3] = reg::kFullBit;  // LEDn full off
  }

  void write(std::uint8_t address, std::span<const std::uint8_t> bytes) override {
    std::unique_lock lock(mutex_);
    enter(lock, address, false, {bytes.begin(), bytes.end()});
    if (bytes.empty()) return;
    std::uint8_t at = bytes[0];
    for (std::size_t i = 1; i < bytes.size(); ++i) {
      store(at, bytes[i]);
      if (regs_[reg::kMode1] & reg::kMode1Ai) at = next(at);
    }
  }

  void read(std::uint8_t address, std::uint8_t reg, std::span<std::uint8_t> out) override {
    std::unique_lock lock(mutex_);
    enter(lock, address, true, {reg});
    for (auto& byte : out) {
      byte = regs_[reg];
      if (regs_[reg::kMode1] & reg::kMode1Ai) reg = next(reg);
    }
  }

  std::string path() const override { return "/dev/i2c-1"; }

  // ---- test controls -----------------------------------------------------------------------------------------
  void set_present(bool present) {
    std::lock_guard lock(mutex_);
    present_ = present;
  }
  void fail_next(I2cError::Kind kind) {
    std::lock_guard lock(mutex_);
    fail_next_ = kind;
  }
  // From now on every transfer blocks (as on a bus with SDA held low) until release().
  void wedge() {
    std::lock_guard lock(mutex_);
    wedged_ = true;
  }
  void release() {
    std::lock_guard lock(mutex_);
    wedged_ = false;
    released_.notify_all();
  }

  std::uint8_t reg(std::uint8_t at) const {
    std::lock_guard lock(mutex_);
    return regs_[at];
  }
  ChannelCounts channel(int ch) const {
    std::lock_guard lock(mutex_);
    const std::size_t base = reg::kLed0OnL + 4 * static_cast<std::size_t>(ch);
    return {static_cast<std::uint16_t>(regs_[base] | regs_[base + 1] << 8),
            static_cast<std::uint16_t>(regs_[base + 2] | regs_[base + 3] << 8)};
  }
  std::vector<Transaction> transactions() const {
    std::lock_guard lock(mutex_);
    return log_;
  }
  void clear_log() {
    std::lock_guard lock(mutex_);
    log_.clear();
  }

 private:
  void enter(std::unique_lock<std::mutex>& lock, std::uint8_t address, bool read, std::vector<std::uint8_t> bytes) {
    released_.wait(lock, [&] { return !wedged_; });
    log_.push_back({read, address, std::move(bytes)});
    if (fail_next_) {
      const auto kind = *fail_next_;
      fail_next_.reset();
      throw I2cError(kind, "injected failure");
    }
    if (!present_ || address != address_) throw I2cError(I2cError::Kind::NoAck, no_ack_message(address, path()));
  }

  static std::uint8_t next(std::uint8_t at) {
    if (at == 0x45 || at == 0xFE) return 0x00;
    return static_cast<std::uint8_t>(at + 1);
  }

  void store(std::uint8_t at, std::uint8_t value) {
    if (at == reg::kPreScale) {
      if (regs_[reg::kMode1] & reg::kMode1Sleep) regs_[at] = value;  // blocked while awake (datasheet 7.3.5)
      return;
    }
    if (at == reg::kMode1) value &= static_cast<std::uint8_t>(~reg::kMode1Restart);  // RESTART clears itself
    regs_[at] = value;
    if (at >= reg::kAllLedOnL && at <= reg::kAllLedOnL + 3)  // ALL_LED loads that register of every channel
      for (int ch = 0; ch < kChannels; ++ch) regs_[reg::kLed0OnL + 4 * ch + (at - reg::kAllLedOnL)] = value;
  }

  const std::uint8_t address_;
  mutable std::mutex mutex_;
  std::condition_variable released_;
  std::array<std::uint8_t, 256> regs_{};
  std::vector<Transaction> log_;
  bool present_ = true;
  bool wedged_ = false;
  std::optional<I2cError::Kind> fail_next_;
};

}  // namespace rcand::plugins::pca9685::testing
