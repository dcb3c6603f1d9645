#include "dynamixel_driver.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <thread>

#include "latency_timer.hpp"

namespace rcand::plugins::dynamixel {

namespace {

using nlohmann::json;
using Clock = std::chrono::steady_clock;
using Items = std::vector<std::pair<std::uint8_t, std::vector<std::uint8_t>>>;

constexpr unsigned kStaleAfterMissedPolls = 3;  // then a joint's position is unknown, never a stale guess
constexpr auto kRebootTime = std::chrono::seconds(2);
constexpr unsigned kStartPingTries = 3;  // as Feetech's bus does: a reply lost once is not a missing servo

std::string id_text(std::uint8_t id) { return "Dynamixel ID " + std::to_string(id); }

std::vector<std::uint8_t> u32(std::uint32_t value) {
  std::vector<std::uint8_t> out;
  put_u32(out, value);
  return out;
}

}  // namespace

DynamixelDriver::DynamixelDriver(DynamixelSettings settings, std::shared_ptr<SerialLink> link, sdk::Logger* log)
    : settings_(std::move(settings)),
      link_(std::move(link)),
      log_(log),
      bus_(std::make_shared<DxlBus>(link_, settings_.reply_timeout)),
      worker_(std::make_unique<SerialWorker>(bus_)) {
  for (const auto& config : settings_.servos) {
    Servo servo;
    servo.config = config;
    servos_.push_back(std::move(servo));
  }
}

DynamixelDriver::~DynamixelDriver() { worker_.reset(); }  // the thread ends before the state it polls into

std::string_view DynamixelDriver::interface_name() const noexcept {
  return settings_.has_wheels() ? DifferentialDrive::kInterface : JointArm::kInterface;
}

void DynamixelDriver::run(SerialWorker::Job job, std::chrono::milliseconds deadline, const char* what) {
  const auto result = worker_->run(std::move(job), deadline);
  switch (result.outcome) {
    case SerialWorker::Outcome::Done: return;
    case SerialWorker::Outcome::Dropped: return;  // a halt superseded it: that is the state the servos should be in
    case SerialWorker::Outcome::Failed: std::rethrow_exception(result.error);
    case SerialWorker::Outcome::TimedOut:
      throw SerialError(std::string(what) + ": not done within " + std::to_string(deadline.count()) + " ms on " + link_->path() +
                        ": the adapter is stalled or unplugged");
  }
}

void DynamixelDriver::init_servo(DxlBus& bus, Servo& servo) const {
  const std::uint8_t id = servo.config.id;
  const ControlTable& t = *servo.model.table;
  const std::string who = id_text(id) + " (" + servo.config.name + ", " + std::string(servo.model.name) + ")";
  servo.hardware_error = bus.read(id, t.hardware_error, 1)[0];
  if (servo.hardware_error != 0) {
    if (!settings_.reboot_on_error)
      throw DxlError(DxlError::Kind::ServoError, id,
                     who + " reports a hardware error: " + hardware_error_text(servo.hardware_error) +
                         ". Find the cause (load, supply voltage, temperature), then reboot it or power-cycle the bus "
                         "(reboot_on_error: true reboots it at start)");
    if (log_) log_->warn("dynamixel: ", who, " hardware error ", hardware_error_text(servo.hardware_error), ": rebooting it");
    bus.reboot(id);
    const auto until = Clock::now() + kRebootTime;
    for (;;) {  // it answers again once its firmware is up
      try {
        bus.ping(id);
        break;
      } catch (const DxlError&) {
        if (Clock::now() > until) throw;
      }
    }
    servo.hardware_error = bus.read(id, t.hardware_error, 1)[0];
    if (servo.hardware_error != 0)
      throw DxlError(DxlError::Kind::ServoError, id,
                     who + " still reports " + hardware_error_text(servo.hardware_error) + " after a reboot");
  }
  const bool joint = servo.config.role == ServoSettings::Role::Joint;
  const std::uint8_t mode = joint ? kModePosition : kModeVelocity;
  bus.write(id, t.bus_watchdog, std::vector<std::uint8_t>{0});  // clears a watchdog that fired (-1) before we came
  if (bus.read(id, t.operating_mode, 1)[0] != mode) {
    bus.write(id, t.torque_enable, std::vector<std::uint8_t>{0});  // the mode is EEPROM: writable with the torque off only
    bus.write(id, t.operating_mode, std::vector<std::uint8_t>{mode});
  }
  const auto limits = bus.read(id, t.velocity_limit, 12);  // velocity limit, max position, min position
  servo.velocity_limit = get_i32(limits, 0);
  if (joint) {
    const double servo_max = degrees_of(servo.model, get_i32(limits, 4));
    const double servo_min = degrees_of(servo.model, get_i32(limits, 8));
    servo.min_deg = std::max(servo.config.min_deg.value_or(servo_min), servo_min);
    servo.max_deg = std::min(servo.config.max_deg.value_or(servo_max), servo_max);
    if (servo.min_deg >= servo.max_deg)
      throw DxlError(DxlError::Kind::BadReply, id,
                     who + ": the configured range and the servo's Min/Max Position Limit do not overlap");
  }
  const auto present = bus.read(id, t.present_velocity, 8);
  servo.present_velocity = get_i32(present, 0);
  servo.present_ticks = get_i32(present, 4);
  servo.read_at = Clock::now();
  servo.profile_acceleration = static_cast<std::uint32_t>(get_i32(bus.read(id, t.profile_acceleration, 4), 0));
  if (joint) {
    // Hold where it is: enabling the torque must not make the arm jump to a goal left over from before.
    servo.goal_ticks =
        std::clamp(*servo.present_ticks, ticks_of(servo.model, servo.min_deg), ticks_of(servo.model, servo.max_deg));
    servo.profile_velocity = velocity_units_of(servo.model, settings_.joint_velocity_dps);
    std::vector<std::uint8_t> block = u32(static_cast<std::uint32_t>(servo.profile_velocity));
    put_u32(block, static_cast<std::uint32_t>(servo.goal_ticks));
    bus.write(id, t.profile_velocity, block);
  } else {
    bus.write(id, t.goal_velocity, u32(0));
  }
  bus.write(id, t.torque_enable, std::vector<std::uint8_t>{1});
  servo.torque_on = true;
  if (settings_.watchdog_units() > 0) bus.write(id, t.bus_watchdog, std::vector<std::uint8_t>{settings_.watchdog_units()});
}

void DynamixelDriver::start() {
  if (const auto timer = read_latency_timer(settings_.port, settings_.sysfs_root)) {
    std::lock_guard lock(mutex_);
    latency_timer_ms_ = timer->milliseconds;
    if (const auto warning = latency_timer_warning(*timer); !warning.empty() && log_) log_->warn("dynamixel: ", warning);
  }
  // Shared with the job: one that outlives its deadline must not write into this stack frame.
  struct Work {
    std::vector<Servo> servos;
    const ControlTable* table = nullptr;
  };
  auto work = std::make_shared<Work>();
  {
    std::lock_guard lock(mutex_);
    work->servos = servos_;
  }
  run(
      [this, work](DxlBus& bus) {
        const ControlTable*& table = work->table;
        for (auto& servo : work->servos) {
          const std::uint8_t id = servo.config.id;
          PingReply reply;
          try {
            reply = bus.ping(id, kStartPingTries);
          } catch (const DxlError& e) {
            if (e.kind() != DxlError::Kind::NoReply) throw;
            std::string found;
            for (const auto& other : bus.scan()) found += (found.empty() ? "" : ", ") + std::to_string(other.id);
            throw DxlError(DxlError::Kind::NoReply, id,
                           std::string(e.what()) + ". A scan at this rate found " +
                               (found.empty() ? std::string("no servo at all") : "IDs " + found));
          }
          const auto model = find_model(reply.model);
          if (!model)
            throw DxlError(DxlError::Kind::BadReply, id,
                           id_text(id) + " is model number " + std::to_string(reply.model) +
                               ", which rcand does not know (X, MX(2.0) and P series are supported)");
          if (table && table != model->table)
            throw DxlError(DxlError::Kind::BadReply, id,
                           id_text(id) + " (" + std::string(model->name) + ") has the " + std::string(model->table->family) +
                               "-series control table, unlike the other servos of this bus: halt must be one sync write, "
                               "so give each family its own bus");
          table = model->table;
          servo.model = *model;
          init_servo(bus, servo);
        }
      },
      std::chrono::milliseconds(2000) + kRebootTime * static_cast<int>(work->servos.size()), "start");
  {
    std::lock_guard lock(mutex_);
    servos_ = std::move(work->servos);
    table_ = work->table;
    started_ = true;
  }
  worker_->set_idle_task([this](DxlBus& bus) { poll(bus); },
                         std::chrono::microseconds(static_cast<long long>(1e6 / settings_.poll_hz)));
  if (log_) {
    std::string what;
    for (const auto& servo : servos_)
      what += (what.empty() ? "" : ", ") + std::to_string(servo.config.id) + " " + servo.config.name + " (" +
              std::string(servo.model.name) + ")";
    log_->info("dynamixel on ", settings_.port, " at ", settings_.baud_rate, " bps: ", what, "; ", fail_safe());
    if (settings_.watchdog_units() == 0)
      log_->warn("dynamixel: watchdog_ms is 0: if rcand dies, the servos keep their last goal");
  }
}

void DynamixelDriver::poll(DxlBus& bus) {
  std::vector<std::uint8_t> ids;
  const ControlTable* table = nullptr;
  {
    std::lock_guard lock(mutex_);
    for (const auto& servo : servos_) ids.push_back(servo.config.id);
    table = table_;
  }
  SyncReadResult result;
  std::string error;
  try {
    result = bus.sync_read(table->present_velocity, 8, ids);
  } catch (const Interrupted&) {
    throw;
  } catch (const std::exception& e) {
    error = e.what();
  }
  // A servo whose reply carried the Alert bit has latched a hardware error: read which (once, until it clears).
  std::vector<std::pair<std::uint8_t, std::uint8_t>> errors;
  for (const auto id : result.alerted) {
    bool known = false;
    {
      std::lock_guard lock(mutex_);
      for (const auto& servo : servos_) known |= servo.config.id == id && servo.hardware_error != 0;
    }
    if (known) continue;
    try {
      errors.emplace_back(id, bus.read(id, table->hardware_error, 1)[0]);
    } catch (const Interrupted&) {
      throw;
    } catch (const std::exception& e) {
      error = e.what();
    }
  }
  const auto now = Clock::now();
  std::lock_guard lock(mutex_);
  ++polls_;
  bool failed = !error.empty();
  for (std::size_t i = 0; i < servos_.size() && i < result.data.size(); ++i) {
    Servo& servo = servos_[i];
    if (const auto& data = result.data[i]) {
      servo.present_velocity = get_i32(*data, 0);
      servo.present_ticks = get_i32(*data, 4);
      servo.read_at = now;
      servo.missed_polls = 0;
      if (std::find(result.alerted.begin(), result.alerted.end(), servo.config.id) == result.alerted.end())
        servo.hardware_error = 0;
    } else {
      failed = true;
      if (++servo.missed_polls >= kStaleAfterMissedPolls) servo.present_ticks.reset();
      if (error.empty()) error = "no status from " + id_text(servo.config.id) + " (" + servo.config.name + ")";
    }
  }
  for (auto& servo : servos_) {
    if (!result.data.empty()) continue;
    if (++servo.missed_polls >= kStaleAfterMissedPolls) servo.present_ticks.reset();
  }
  for (const auto& [id, bits] : errors) {
    for (auto& servo : servos_)
      if (servo.config.id == id) servo.hardware_error = bits;
    const std::string text =
        id_text(id) + " hardware error: " + hardware_error_text(bits) + " (it has stopped; reboot it once the cause is fixed)";
    last_error_ = text;
    if (log_) log_->error("dynamixel: ", text);
  }
  if (failed) {
    ++poll_failures_;
    last_error_ = error;
  }
}

std::int32_t DynamixelDriver::hold_ticks(const Servo& servo, Clock::time_point now) const {
  if (!servo.present_ticks) return servo.goal_ticks;  // no idea where it is: keep the last goal rather than guess
  // The joint kept moving since it was read: extrapolate to now, but never past the goal it was heading for.
  const double age_s = std::chrono::duration<double>(now - servo.read_at).count();
  const double ticks_per_s = servo.present_velocity * servo.model.velocity_unit_rpm / 60.0 * servo.model.ticks_per_rev;
  const double ahead = static_cast<double>(*servo.present_ticks) + ticks_per_s * std::min(age_s, 0.1);
  const auto [low, high] = std::minmax(*servo.present_ticks, servo.goal_ticks);
  return std::clamp(static_cast<std::int32_t>(std::lround(ahead)), low, high);
}

std::int32_t DynamixelDriver::wheel_units(const Servo& servo, double fraction) const {
  if (!std::isfinite(fraction)) fraction = 0.0;
  fraction = std::clamp(fraction, -1.0, 1.0);
  if (servo.config.reverse) fraction = -fraction;
  double max_units = servo.velocity_limit;
  if (settings_.wheel_max_rpm) max_units = std::min(max_units, *settings_.wheel_max_rpm / servo.model.velocity_unit_rpm);
  return static_cast<std::int32_t>(std::lround(fraction * max_units));
}

void DynamixelDriver::set_wheel_speeds(double left, double right) {
  Items items;
  std::uint16_t address = 0;
  std::uint64_t generation = 0;
  {
    std::lock_guard lock(mutex_);
    if (!started_) throw std::logic_error("dynamixel: not started");
    if (!settings_.has_wheels()) throw std::logic_error("dynamixel on " + settings_.port + " has no wheels (servos[].wheel)");
    for (auto& servo : servos_) {
      if (servo.config.role == ServoSettings::Role::Joint) continue;
      servo.goal_velocity = wheel_units(servo, servo.config.role == ServoSettings::Role::LeftWheel ? left : right);
      items.emplace_back(servo.config.id, u32(static_cast<std::uint32_t>(servo.goal_velocity)));
    }
    address = table_->goal_velocity;
    ++commands_;
    generation = generation_->load();
  }
  run(
      [address, items = std::move(items), generation, current = generation_](DxlBus& bus) {
        if (current->load() == generation) bus.sync_write(address, 4, items);  // else a halt came first: stale
      },
      settings_.command_timeout, "wheel update");
}

void DynamixelDriver::set_joint_targets(const std::vector<sdk::JointTarget>& targets) {
  Items items;
  std::uint16_t address = 0;
  std::uint64_t generation = 0;
  {
    std::lock_guard lock(mutex_);
    if (!started_) throw std::logic_error("dynamixel: not started");
    // Everything is checked before anything changes: a refused command applies nothing.
    std::vector<std::pair<Servo*, const sdk::JointTarget*>> plan;
    for (const auto& target : targets) {
      auto it = std::find_if(servos_.begin(), servos_.end(), [&](const Servo& s) {
        return s.config.role == ServoSettings::Role::Joint && s.config.name == target.joint;
      });
      if (it == servos_.end()) throw std::invalid_argument("joint '" + target.joint + "': not a joint of this Dynamixel bus");
      if (!std::isfinite(target.position_deg) || target.position_deg < it->min_deg || target.position_deg > it->max_deg)
        throw std::invalid_argument("joint '" + target.joint + "': " + std::to_string(target.position_deg) +
                                    " deg is outside the servo's range [" + std::to_string(it->min_deg) + ", " +
                                    std::to_string(it->max_deg) + "]");
      if (!std::isfinite(target.velocity_dps) || target.velocity_dps < 0)
        throw std::invalid_argument("joint '" + target.joint + "': velocity_dps must be 0 (default) or above");
      plan.emplace_back(&*it, &target);
    }
    for (auto& [servo, target] : plan) {
      servo->commanded_dps = target->velocity_dps > 0 ? target->velocity_dps : settings_.joint_velocity_dps;
      servo->profile_velocity = velocity_units_of(servo->model, servo->commanded_dps);
      servo->goal_ticks = ticks_of(servo->model, target->position_deg);
      std::vector<std::uint8_t> block = u32(static_cast<std::uint32_t>(servo->profile_velocity));
      put_u32(block, static_cast<std::uint32_t>(servo->goal_ticks));
      items.emplace_back(servo->config.id, std::move(block));
    }
    address = table_->profile_velocity;
    ++commands_;
    generation = generation_->load();
  }
  if (items.empty()) return;
  run(
      [address, items = std::move(items), generation, current = generation_](DxlBus& bus) {
        if (current->load() == generation) bus.sync_write(address, 8, items);
      },
      settings_.command_timeout, "joint targets");
}

std::vector<sdk::JointState> DynamixelDriver::joint_states() const {
  std::lock_guard lock(mutex_);
  std::vector<sdk::JointState> states;
  for (const auto& servo : servos_) {
    if (servo.config.role != ServoSettings::Role::Joint) continue;
    sdk::JointState state;
    state.joint = servo.config.name;
    if (started_ && servo.present_ticks) state.position_deg = degrees_of(servo.model, *servo.present_ticks);
    state.target_deg = started_ ? degrees_of(servo.model, servo.goal_ticks) : 0.0;
    state.moving = servo.present_ticks && (servo.present_velocity != 0 ||
                                           std::abs(*servo.present_ticks - servo.goal_ticks) > servo.model.ticks_per_rev / 360);
    state.velocity_dps = state.moving ? servo.commanded_dps : 0.0;
    state.torque_on = servo.torque_on;
    states.push_back(std::move(state));
  }
  return states;
}

void DynamixelDriver::halt() noexcept {
  try {
    Items items;
    std::uint16_t address = 0;
    {
      std::lock_guard lock(mutex_);
      generation_->fetch_add(1);
      ++halts_;
      if (!started_) return;
      const auto now = Clock::now();
      // One block for every servo: goal velocity 0, its profile acceleration and velocity unchanged, goal position
      // = where it is (joints; a wheel in velocity mode ignores it).
      for (auto& servo : servos_) {
        servo.goal_velocity = 0;
        if (servo.config.role == ServoSettings::Role::Joint) servo.goal_ticks = hold_ticks(servo, now);
        std::vector<std::uint8_t> block = u32(0);
        put_u32(block, servo.profile_acceleration);
        put_u32(block, static_cast<std::uint32_t>(servo.profile_velocity));
        put_u32(block, static_cast<std::uint32_t>(
                           servo.config.role == ServoSettings::Role::Joint ? servo.goal_ticks : servo.present_ticks.value_or(0)));
        items.emplace_back(servo.config.id, std::move(block));
      }
      address = table_->goal_velocity;
    }
    const auto result = worker_->urgent([address, items = std::move(items)](DxlBus& bus) { bus.sync_write(address, 16, items); },
                                        settings_.halt_deadline);
    if (result.outcome == SerialWorker::Outcome::Done || result.outcome == SerialWorker::Outcome::Dropped) return;
    std::string why = result.outcome == SerialWorker::Outcome::TimedOut
                          ? "not written within " + std::to_string(settings_.halt_deadline.count()) + " ms (adapter stalled?)"
                          : "failed";
    if (result.error) try {
        std::rethrow_exception(result.error);
      } catch (const std::exception& e) {
        why += std::string(": ") + e.what();
      }
    why += settings_.watchdog_units() ? "; the Bus Watchdog stops the servos once polls stop reaching them"
                                      : "; no Bus Watchdog configured: the servos may still move";
    {
      std::lock_guard lock(mutex_);
      ++halts_unconfirmed_;
      last_error_ = "halt " + why;
    }
    if (log_) log_->error("dynamixel halt ", why);
  } catch (...) {  // allocation only
  }
}

void DynamixelDriver::shutdown() noexcept { halt(); }

void DynamixelDriver::reboot_servo(std::uint8_t id) {
  auto copy = std::make_shared<Servo>();
  {
    std::lock_guard lock(mutex_);
    if (!started_) throw std::logic_error("dynamixel: not started");
    const auto it = std::find_if(servos_.begin(), servos_.end(), [&](const Servo& s) { return s.config.id == id; });
    if (it == servos_.end()) throw std::invalid_argument(id_text(id) + " is not on this bus");
    *copy = *it;
    it->torque_on = false;
  }
  run(
      [this, id, copy](DxlBus& bus) {
        bus.reboot(id);
        const auto until = Clock::now() + kRebootTime;
        for (;;) {
          try {
            bus.ping(id);
            break;
          } catch (const DxlError&) {
            if (Clock::now() > until) throw;
          }
        }
        init_servo(bus, *copy);
      },
      settings_.command_timeout + kRebootTime + std::chrono::seconds(1), "reboot");
  std::lock_guard lock(mutex_);
  for (auto& servo : servos_)
    if (servo.config.id == id) servo = *copy;
  if (log_) log_->info("dynamixel: ", id_text(id), " rebooted; holding at ", degrees_of(copy->model, copy->goal_ticks), " deg");
}

std::string DynamixelDriver::fail_safe() const {
  const std::string halt = "halt = one sync write: wheels to 0, joints hold their position with the torque on";
  if (settings_.watchdog_units() == 0)
    return "fail-safe: " + halt + "; NO Bus Watchdog (watchdog_ms: 0): if rcand dies, the servos keep their last goal";
  return "fail-safe: Bus Watchdog " + std::to_string(settings_.watchdog_units() * 20) +
         " ms on every servo: if rcand dies or the bus is cut, they stop by themselves (torque stays on); " + halt;
}

std::uint64_t DynamixelDriver::polls() const {
  std::lock_guard lock(mutex_);
  return polls_;
}

nlohmann::json DynamixelDriver::status() const {
  std::lock_guard lock(mutex_);
  json servos = json::array();
  for (const auto& servo : servos_) {
    json item{{"id", servo.config.id},
              {"name", servo.config.name},
              {"role", servo.config.role == ServoSettings::Role::Joint ? "joint" : "wheel"},
              {"model", started_ ? json(std::string(servo.model.name)) : json(nullptr)},
              {"torque_on", servo.torque_on},
              {"hardware_error", servo.hardware_error ? json(hardware_error_text(servo.hardware_error)) : json(nullptr)}};
    if (started_ && servo.config.role == ServoSettings::Role::Joint) {
      item["position_deg"] = servo.present_ticks ? json(degrees_of(servo.model, *servo.present_ticks)) : json(nullptr);
      item["target_deg"] = degrees_of(servo.model, servo.goal_ticks);
    } else if (started_) {
      item["velocity_rpm"] = servo.present_velocity * servo.model.velocity_unit_rpm;
    }
    servos.push_back(std::move(item));
  }
  return {{"port", settings_.port},
          {"baud_rate", settings_.baud_rate},
          {"latency_timer_ms", latency_timer_ms_ ? json(*latency_timer_ms_) : json(nullptr)},
          {"started", started_},
          {"servos", std::move(servos)},
          {"commands", commands_},
          {"polls", polls_},
          {"poll_failures", poll_failures_},
          {"halts", halts_},
          {"halts_unconfirmed", halts_unconfirmed_},
          {"last_error", last_error_.empty() ? json(nullptr) : json(last_error_)},
          {"watchdog_ms", settings_.watchdog_units() * 20},
          {"fail_safe", fail_safe()}};
}

}  // namespace rcand::plugins::dynamixel
