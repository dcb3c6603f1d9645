#include "servo_emulator.hpp"

#include <poll.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>

#include "models.hpp"

namespace rcand::plugins::dynamixel::testing {

namespace {

constexpr const ControlTable& T = kTableX;
constexpr std::uint16_t kModelNumber = 0, kFirmware = 6, kMoving = 122;
constexpr std::uint8_t kErrInstruction = 2, kErrRange = 4, kErrAccess = 7;
constexpr double kUnitRpm = 0.229;

bool goal_address(std::uint16_t at) { return at >= T.goal_velocity && at < T.goal_position + 4; }

}  // namespace

void ServoEmulator::Servo::set_i32(std::uint16_t at, std::int32_t value) {
  for (int i = 0; i < 4; ++i) table[at + i] = static_cast<std::uint8_t>(static_cast<std::uint32_t>(value) >> (8 * i));
}

ServoEmulator::ServoEmulator(int master, std::vector<std::uint8_t> ids, std::uint16_t model)
    : master_(master), model_(model), last_tick_(Clock::now()) {
  for (const auto id : ids) reset(servos_[id], id);
  thread_ = std::thread([this] { loop(); });
}

ServoEmulator::~ServoEmulator() {
  stop_ = true;
  thread_.join();
}

void ServoEmulator::reset(Servo& s, std::uint8_t id) {
  // Power-up values of an XM430-W350 (e-Manual control table): position mode, limits 0..4095, torque off.
  const auto position = static_cast<std::int32_t>(std::lround(s.position));
  s.table.fill(0);
  s.table[kModelNumber] = static_cast<std::uint8_t>(model_ & 0xFF);
  s.table[kModelNumber + 1] = static_cast<std::uint8_t>(model_ >> 8);
  s.table[kFirmware] = 45;
  s.table[7] = id;
  s.table[T.operating_mode] = kModePosition;
  s.set_i32(T.velocity_limit, 265);
  s.set_i32(T.max_position_limit, 4095);
  s.set_i32(T.min_position_limit, 0);
  s.set_i32(T.goal_position, position);
  s.set_i32(T.present_position, position);
  s.last_heard = Clock::now();
}

void ServoEmulator::set_present(std::uint8_t id, bool present) {
  std::lock_guard lock(mutex_);
  servos_.at(id).present = present;
}

void ServoEmulator::hold_next_reply(std::uint8_t id) {
  std::lock_guard lock(mutex_);
  hold_next_.insert(id);
}

void ServoEmulator::set_hardware_error(std::uint8_t id, std::uint8_t bits) {
  std::lock_guard lock(mutex_);
  auto& s = servos_.at(id);
  s.table[T.hardware_error] = bits;
  if (bits) s.table[T.torque_enable] = 0;  // a hardware error (shutdown) drops the torque
}

void ServoEmulator::set_position(std::uint8_t id, std::int32_t ticks) {
  std::lock_guard lock(mutex_);
  auto& s = servos_.at(id);
  s.position = ticks;
  s.set_i32(T.present_position, ticks);
  s.set_i32(T.goal_position, ticks);
}

void ServoEmulator::set_wire_baud(int baud) {
  std::lock_guard lock(mutex_);
  wire_baud_ = baud;
}

ServoEmulator::Servo ServoEmulator::servo(std::uint8_t id) const {
  std::lock_guard lock(mutex_);
  return servos_.at(id);
}

std::vector<ServoEmulator::Received> ServoEmulator::received() const {
  std::lock_guard lock(mutex_);
  return received_;
}

void ServoEmulator::clear_received() {
  std::lock_guard lock(mutex_);
  received_.clear();
}

bool ServoEmulator::wait_until(const std::function<bool(const std::map<std::uint8_t, Servo>&)>& predicate,
                               std::chrono::milliseconds timeout) {
  std::unique_lock lock(mutex_);
  return changed_.wait_for(lock, timeout, [&] { return predicate(servos_); });
}

bool ServoEmulator::wait_for_packets(const std::function<bool(const std::vector<Received>&)>& predicate,
                                     std::chrono::milliseconds timeout) {
  std::unique_lock lock(mutex_);
  return changed_.wait_for(lock, timeout, [&] { return predicate(received_); });
}

void ServoEmulator::loop() {
  std::array<std::uint8_t, 512> chunk{};
  while (!stop_) {
    pollfd pfd{master_, POLLIN, 0};
    ::poll(&pfd, 1, 1);  // 1 ms: the motion and watchdog tick
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

void ServoEmulator::reply(std::uint8_t id, std::uint8_t error, std::span<const std::uint8_t> params) {
  const auto& s = servos_.at(id);
  std::vector<std::uint8_t> body{static_cast<std::uint8_t>(error | (s.table[T.hardware_error] ? 0x80 : 0))};
  body.insert(body.end(), params.begin(), params.end());
  const auto packet = encode(id, inst::kStatus, body);
  auto& to = hold_next_.erase(id) ? held_ : outbox_;
  to.insert(to.end(), packet.begin(), packet.end());
}

void ServoEmulator::handle(const Packet& p, Clock::time_point now) {
  if (p.code == inst::kStatus) return;  // another servo's reply (none here, but a real bus carries them)
  received_.push_back({now, p});
  outbox_.insert(outbox_.end(), held_.begin(), held_.end());
  held_.clear();
  const auto hear = [&](std::uint8_t id) -> Servo* {
    auto it = servos_.find(id);
    if (it == servos_.end() || !it->second.present) return nullptr;
    it->second.last_heard = now;
    return &it->second;
  };
  // Writes one servo's bytes the way its firmware would: EEPROM only with the torque off, goals refused while
  // the watchdog has fired, the watchdog itself only cleared (0) once fired.
  const auto store = [&](Servo& s, std::uint16_t at, std::span<const std::uint8_t> data) -> std::uint8_t {
    if (at + data.size() > s.table.size()) return kErrRange;
    if (at < kFirstRamAddressX && s.table[T.torque_enable]) return kErrAccess;
    if (goal_address(at) && s.table[T.bus_watchdog] == 0xFF) return kErrAccess;
    for (std::size_t i = 0; i < data.size(); ++i) s.table[at + i] = data[i];
    return 0;
  };

  const std::span<const std::uint8_t> params(p.params);
  switch (p.code) {
    case inst::kPing:
      if (p.id == kBroadcastId) {
        for (auto& [id, s] : servos_)
          if (hear(id)) reply(id, 0, std::vector<std::uint8_t>{s.table[0], s.table[1], s.table[kFirmware]});
      } else if (auto* s = hear(p.id)) {
        reply(p.id, 0, std::vector<std::uint8_t>{s->table[0], s->table[1], s->table[kFirmware]});
      }
      return;
    case inst::kRead: {
      auto* s = hear(p.id);
      if (!s) return;
      if (params.size() != 4) return reply(p.id, kErrInstruction, {});
      const auto at = get_u16(params, 0), len = get_u16(params, 2);
      if (at + len > s->table.size()) return reply(p.id, kErrRange, {});
      return reply(p.id, 0, std::span(s->table).subspan(at, len));
    }
    case inst::kWrite: {
      auto* s = hear(p.id);
      if (!s) return;
      if (params.size() < 3) return reply(p.id, kErrInstruction, {});
      return reply(p.id, store(*s, get_u16(params, 0), params.subspan(2)), {});
    }
    case inst::kReboot: {
      auto* s = hear(p.id);
      if (!s) return;
      reply(p.id, 0, {});
      ++s->reboots;
      reset(*s, p.id);
      return;
    }
    case inst::kSyncWrite: {
      if (params.size() < 4) return;
      const auto at = get_u16(params, 0), len = get_u16(params, 2);
      for (std::size_t i = 4; i + 1 + len <= params.size(); i += 1u + len)
        if (auto* s = hear(params[i])) store(*s, at, params.subspan(i + 1, len));
      return;
    }
    case inst::kSyncRead: {
      if (params.size() < 4) return;
      const auto at = get_u16(params, 0), len = get_u16(params, 2);
      for (std::size_t i = 4; i < params.size(); ++i)  // in the order asked
        if (auto* s = hear(params[i])) {
          if (at + len > s->table.size()) reply(params[i], kErrRange, {});
          else reply(params[i], 0, std::span(s->table).subspan(at, len));
        }
      return;
    }
    default:
      if (auto* s = hear(p.id); s && p.id != kBroadcastId) reply(p.id, kErrInstruction, {});
  }
}

void ServoEmulator::tick(Clock::time_point now) {
  const double dt = std::chrono::duration<double>(now - last_tick_).count();
  last_tick_ = now;
  for (auto& [id, s] : servos_) {
    const bool torque = s.table[T.torque_enable] != 0;
    const std::uint8_t watchdog = s.table[T.bus_watchdog];
    if (torque && watchdog != 0 && watchdog != 0xFF && now - s.last_heard > std::chrono::milliseconds(20 * watchdog)) {
      // Bus Watchdog error: stop (e-Manual, Bus Watchdog(98)), torque stays on.
      s.set_i32(T.goal_velocity, 0);
      s.set_i32(T.goal_position, static_cast<std::int32_t>(std::lround(s.position)));
      s.table[T.bus_watchdog] = 0xFF;
      ++s.watchdog_trips;
      s.tripped_at = now;
    }
    double velocity_units = 0.0;  // signed, in 0.229 rpm
    if (torque && s.table[T.operating_mode] == kModeVelocity) {
      velocity_units = s.i32(T.goal_velocity);
    } else if (torque && s.table[T.operating_mode] == kModePosition) {
      const double goal = s.i32(T.goal_position), profile = s.i32(T.profile_velocity);
      const double max_step = profile > 0 ? profile * kUnitRpm / 60.0 * 4096.0 * dt : std::abs(goal - s.position);
      const double step = std::clamp(goal - s.position, -max_step, max_step);
      velocity_units = dt > 0 ? step / dt / 4096.0 * 60.0 / kUnitRpm : 0.0;
      s.position += step;
    }
    if (s.table[T.operating_mode] == kModeVelocity) s.position += velocity_units * kUnitRpm / 60.0 * 4096.0 * dt;
    s.set_i32(T.present_velocity, static_cast<std::int32_t>(std::lround(velocity_units)));
    s.set_i32(T.present_position, static_cast<std::int32_t>(std::lround(s.position)));
    s.table[kMoving] = velocity_units != 0.0;
  }
}

}  // namespace rcand::plugins::dynamixel::testing
