#include "sts_emulator.hpp"

#include <poll.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>

#include "sts_table.hpp"

namespace rcand::plugins::feetech::testing {

namespace {

constexpr double kStsFullSpeed = 3072.0;  // steps/s: what a goal speed of 0 means in position mode
constexpr std::uint8_t kFirstRamAddress = 40;

void put_table_u16(std::array<std::uint8_t, 256>& table, std::uint8_t at, std::uint16_t value) {
  table[at] = static_cast<std::uint8_t>(value & 0xFF);
  table[at + 1] = static_cast<std::uint8_t>(value >> 8);
}

}  // namespace

StsEmulator::StsEmulator(int master, std::vector<std::uint8_t> ids, std::uint16_t model)
    : master_(master), model_(model), last_tick_(Clock::now()) {
  for (const auto id : ids) {
    // Power-up values of an STS3215 (lerobot tables.py addresses): position mode, limits 0..4095, torque off,
    // EEPROM locked, torque limit 100 %, 12.0 V, 30 C.
    Servo& s = servos_[id];
    put_table_u16(s.table, sts::kModelNumber, model_);
    s.table[sts::kId] = id;
    s.table[sts::kOperatingMode] = sts::kModePosition;
    put_table_u16(s.table, sts::kMinAngleLimit, 0);
    put_table_u16(s.table, sts::kMaxAngleLimit, 4095);
    put_table_u16(s.table, sts::kGoalPosition, 2048);
    put_table_u16(s.table, sts::kPresentPosition, 2048);
    put_table_u16(s.table, sts::kTorqueLimit, 1000);
    s.table[sts::kLock] = 1;
    s.table[sts::kPresentVoltage] = 120;
    s.table[sts::kPresentTemperature] = 30;
  }
  thread_ = std::thread([this] { loop(); });
}

StsEmulator::~StsEmulator() {
  stop_ = true;
  thread_.join();
}

void StsEmulator::set_present(std::uint8_t id, bool present) {
  std::lock_guard lock(mutex_);
  servos_.at(id).present = present;
}

void StsEmulator::set_position(std::uint8_t id, std::int32_t ticks) {
  std::lock_guard lock(mutex_);
  auto& s = servos_.at(id);
  s.position = ticks;
  put_table_u16(s.table, sts::kPresentPosition, encode_sign_magnitude(ticks, sts::kSignBit));
  put_table_u16(s.table, sts::kGoalPosition, encode_sign_magnitude(ticks, sts::kSignBit));
}

void StsEmulator::set_angle_limits(std::uint8_t id, std::uint16_t min_ticks, std::uint16_t max_ticks) {
  std::lock_guard lock(mutex_);
  auto& s = servos_.at(id);
  put_table_u16(s.table, sts::kMinAngleLimit, min_ticks);
  put_table_u16(s.table, sts::kMaxAngleLimit, max_ticks);
}

void StsEmulator::set_operating_mode(std::uint8_t id, std::uint8_t mode) {
  std::lock_guard lock(mutex_);
  servos_.at(id).table[sts::kOperatingMode] = mode;
}

void StsEmulator::set_status_error(std::uint8_t id, std::uint8_t bits) {
  std::lock_guard lock(mutex_);
  status_errors_[id] = bits;
}

void StsEmulator::set_wire_baud(int baud) {
  std::lock_guard lock(mutex_);
  wire_baud_ = baud;
}

StsEmulator::Servo StsEmulator::servo(std::uint8_t id) const {
  std::lock_guard lock(mutex_);
  return servos_.at(id);
}

std::vector<StsEmulator::Received> StsEmulator::received() const {
  std::lock_guard lock(mutex_);
  return received_;
}

void StsEmulator::clear_received() {
  std::lock_guard lock(mutex_);
  received_.clear();
}

bool StsEmulator::wait_until(const std::function<bool(const std::map<std::uint8_t, Servo>&)>& predicate,
                             std::chrono::milliseconds timeout) {
  std::unique_lock lock(mutex_);
  return changed_.wait_for(lock, timeout, [&] { return predicate(servos_); });
}

bool StsEmulator::wait_for_packets(const std::function<bool(const std::vector<Received>&)>& predicate,
                                   std::chrono::milliseconds timeout) {
  std::unique_lock lock(mutex_);
  return changed_.wait_for(lock, timeout, [&] { return predicate(received_); });
}

void StsEmulator::loop() {
  std::array<std::uint8_t, 512> chunk{};
  while (!stop_) {
    pollfd pfd{master_, POLLIN, 0};
    ::poll(&pfd, 1, 1);  // 1 ms: the motion tick
    const auto n = ::read(master_, chunk.data(), chunk.size());
    std::vector<std::uint8_t> out;
    int baud = 0;
    {
      std::lock_guard lock(mutex_);
      const auto now = Clock::now();
      if (n > 0) {
        decoder_.feed(std::span(chunk).first(static_cast<std::size_t>(n)));
        while (auto packet = decoder_.next()) handle(*packet, now);
      }
      tick(now);
      out.swap(outbox_);
      baud = wire_baud_;
      changed_.notify_all();
    }
    if (out.empty()) continue;
    if (baud > 0)  // the replies' time on the wire
      std::this_thread::sleep_for(std::chrono::microseconds(static_cast<long long>(out.size()) * 10'000'000 / baud));
    std::size_t done = 0;
    while (done < out.size()) {
      const auto w = ::write(master_, out.data() + done, out.size() - done);
      if (w > 0) done += static_cast<std::size_t>(w);
      else if (stop_) break;
    }
  }
}

void StsEmulator::reply(std::uint8_t id, std::span<const std::uint8_t> params) {
  const auto it = status_errors_.find(id);
  const auto packet = encode(id, it == status_errors_.end() ? 0 : it->second, params);
  outbox_.insert(outbox_.end(), packet.begin(), packet.end());
}

std::uint8_t StsEmulator::store(Servo& s, std::uint8_t at, std::span<const std::uint8_t> data) {
  if (at + data.size() > s.table.size()) return 0;
  // EEPROM stays as it is while locked (the Lock register itself is RAM).
  if (at < kFirstRamAddress && s.table[sts::kLock] != 0) {
    ++s.eeprom_refused;
    return 0;
  }
  for (std::size_t i = 0; i < data.size(); ++i) s.table[at + i] = data[i];
  return 0;
}

void StsEmulator::handle(const Packet& p, Clock::time_point now) {
  received_.push_back({now, p});
  const auto hear = [&](std::uint8_t id) -> Servo* {
    auto it = servos_.find(id);
    if (it == servos_.end() || !it->second.present) return nullptr;
    return &it->second;
  };
  const std::span<const std::uint8_t> params(p.params);
  switch (p.code) {
    case inst::kPing:
      if (hear(p.id)) reply(p.id, {});
      return;
    case inst::kRead: {
      auto* s = hear(p.id);
      if (!s || params.size() != 2 || params[0] + params[1] > 256) return;
      return reply(p.id, std::span(s->table).subspan(params[0], params[1]));
    }
    case inst::kWrite: {
      auto* s = hear(p.id);
      if (!s || params.size() < 2) return;
      store(*s, params[0], params.subspan(1));
      return reply(p.id, {});
    }
    case inst::kRegWrite: {
      auto* s = hear(p.id);
      if (!s || params.size() < 2) return;
      for (std::size_t i = 1; i < params.size() && params[0] + i - 1 < 256; ++i) s->registered[params[0] + i - 1] = params[i];
      s->pending.emplace_back(params[0], static_cast<std::uint8_t>(params.size() - 1));
      return reply(p.id, {});
    }
    case inst::kAction:
      for (auto& [id, s] : servos_) {
        if (!s.present || (p.id != kBroadcastId && p.id != id)) continue;
        for (const auto& [at, len] : s.pending) store(s, at, std::span(s.registered).subspan(at, len));
        s.pending.clear();
      }
      return;
    case inst::kSyncWrite: {
      if (params.size() < 2) return;
      const std::uint8_t at = params[0], len = params[1];
      for (std::size_t i = 2; i + 1 + len <= params.size(); i += 1u + len)
        if (auto* s = hear(params[i])) store(*s, at, params.subspan(i + 1, len));
      return;
    }
    case inst::kSyncRead: {
      if (params.size() < 2) return;
      const std::uint8_t at = params[0], len = params[1];
      for (std::size_t i = 2; i < params.size(); ++i)  // in the order asked
        if (auto* s = hear(params[i]); s && at + len <= 256) reply(params[i], std::span(s->table).subspan(at, len));
      return;
    }
    default: return;
  }
}

void StsEmulator::tick(Clock::time_point now) {
  const double dt = std::chrono::duration<double>(now - last_tick_).count();
  last_tick_ = now;
  for (auto& [id, s] : servos_) {
    const bool torque = s.table[sts::kTorqueEnable] != 0;
    double speed = 0.0;  // steps/s, signed
    if (torque && s.table[sts::kOperatingMode] == sts::kModeWheel) {
      speed = decode_sign_magnitude(get_u16(s.table, sts::kGoalSpeed), sts::kSignBit);
      s.position = std::fmod(s.position + speed * dt + 4096.0, 4096.0);
    } else if (torque && s.table[sts::kOperatingMode] == sts::kModePosition) {
      const double goal = decode_sign_magnitude(get_u16(s.table, sts::kGoalPosition), sts::kSignBit);
      const double limit = std::abs(decode_sign_magnitude(get_u16(s.table, sts::kGoalSpeed), sts::kSignBit));
      const double max_step = (limit > 0 ? limit : kStsFullSpeed) * dt;
      const double step = std::clamp(goal - s.position, -max_step, max_step);
      speed = dt > 0 ? step / dt : 0.0;
      s.position += step;
    }
    const auto ticks = static_cast<std::int32_t>(std::lround(s.position));
    put_table_u16(s.table, sts::kPresentPosition, encode_sign_magnitude(ticks, sts::kSignBit));
    put_table_u16(s.table, sts::kPresentSpeed,
                  encode_sign_magnitude(static_cast<std::int32_t>(std::lround(speed)), sts::kSignBit));
    s.table[sts::kMoving] = speed != 0.0;
  }
}

}  // namespace rcand::plugins::feetech::testing
