#include "feetech_driver.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace rcand::plugins::feetech {

namespace {

using nlohmann::json;
using FeetechClock = std::chrono::steady_clock;
constexpr std::int32_t kCentreTicks = 2048;
constexpr std::int32_t kMaxSpeedField = (1 << sts::kSignBit) - 1;

std::vector<std::uint8_t> one_byte(std::uint8_t value) { return {value}; }

}  // namespace

FeetechDriver::FeetechDriver(FeetechSettings settings, std::shared_ptr<SerialLink> link, sdk::Logger* log)
    : settings_(std::move(settings)),
      link_(std::move(link)),
      log_(log),
      bus_(std::make_shared<FeetechBus>(link_, settings_.reply_timeout, settings_.retries)),
      worker_(std::make_unique<FeetechWorker>(bus_)) {
  for (const auto& config : settings_.servos) {
    Servo servo;
    servo.config = config;
    servo.torque_limit = static_cast<std::uint16_t>(std::lround(config.torque_limit_pct * 10));
    servos_.push_back(std::move(servo));
  }
}

FeetechDriver::~FeetechDriver() { worker_.reset(); }  // the thread ends before the state it polls into

std::string_view FeetechDriver::interface_name() const noexcept {
  return settings_.has_wheels() ? DifferentialDrive::kInterface : JointArm::kInterface;
}

std::string FeetechDriver::who(const Servo& servo) const {
  return "Feetech servo ID " + std::to_string(servo.config.id) + " (" + servo.config.name + ") on " + settings_.port;
}

std::int32_t FeetechDriver::ticks_of(const Servo& servo, double deg) const {
  const double sign = servo.config.invert ? -1.0 : 1.0;
  return kCentreTicks +
         static_cast<std::int32_t>(std::lround(sign * (deg - servo.config.offset_deg) * servo.model.ticks_per_rev / 360.0));
}

double FeetechDriver::degrees_of(const Servo& servo, std::int32_t ticks) const {
  const double sign = servo.config.invert ? -1.0 : 1.0;
  return servo.config.offset_deg + sign * (ticks - kCentreTicks) * 360.0 / servo.model.ticks_per_rev;
}

std::int32_t FeetechDriver::joint_speed(const Servo& servo, double dps) const {
  if (servo.config.max_velocity_dps) dps = std::min(dps, *servo.config.max_velocity_dps);
  const double steps = dps * servo.model.ticks_per_rev / 360.0;
  // Never 0: in position mode a goal speed of 0 means "as fast as the servo can".
  return std::clamp(static_cast<std::int32_t>(std::lround(steps)), 1, static_cast<std::int32_t>(servo.model.max_speed));
}

std::int32_t FeetechDriver::wheel_speed(const Servo& servo, double fraction) const {
  if (!std::isfinite(fraction)) fraction = 0.0;
  fraction = std::clamp(fraction, -1.0, 1.0);
  if (servo.config.invert) fraction = -fraction;
  double max_steps = servo.model.max_speed;
  if (settings_.wheel_max_rpm)
    max_steps = std::min<double>(*settings_.wheel_max_rpm / 60.0 * servo.model.ticks_per_rev, kMaxSpeedField);
  return static_cast<std::int32_t>(std::lround(fraction * max_steps));
}

std::vector<std::uint8_t> FeetechDriver::block(const Servo& servo, std::int32_t goal_ticks, std::int32_t speed) const {
  std::vector<std::uint8_t> out;
  put_u16(out, encode_sign_magnitude(goal_ticks, sts::kSignBit));
  put_u16(out, 0);  // goal time 0: travel at the goal speed
  put_u16(out, encode_sign_magnitude(speed, sts::kSignBit));
  put_u16(out, servo.torque_limit);
  return out;
}

void FeetechDriver::run(FeetechWorker::Job job, std::chrono::milliseconds deadline, const char* what) {
  const auto result = worker_->run(std::move(job), deadline);
  switch (result.outcome) {
    case FeetechWorker::Outcome::Done: return;
    case FeetechWorker::Outcome::Dropped: return;  // a halt superseded it: that is the state the servos should be in
    case FeetechWorker::Outcome::Failed: std::rethrow_exception(result.error);
    case FeetechWorker::Outcome::TimedOut:
      throw SerialError(std::string(what) + ": not done within " + std::to_string(deadline.count()) + " ms on " + link_->path() +
                        ": the adapter is stalled or unplugged");
  }
}

void FeetechDriver::init_servo(FeetechBus& bus, Servo& servo) const {
  const std::uint8_t id = servo.config.id;
  try {
    bus.ping(id);
  } catch (const FeetechError& e) {
    throw FeetechError(e.kind(), id, who(servo) + " is missing: " + e.what());
  }
  const auto number = get_u16(bus.read(id, sts::kModelNumber, 2), 0);
  const auto model = find_model(number);
  if (!model)
    throw FeetechError(FeetechError::Kind::BadReply, id,
                       who(servo) + " is model number " + std::to_string(number) +
                           ", which this driver does not know (STS3215 = 777, STS3250 = 2825; SCS servos are not supported)");
  if (servo.config.model && *servo.config.model != model->name)
    throw FeetechError(FeetechError::Kind::BadReply, id,
                       who(servo) + " is an " + std::string(model->name) + ", but the config says " + *servo.config.model);
  servo.model = *model;
  const bool joint = servo.config.role == FeetechServoSettings::Role::Joint;
  const std::uint8_t mode = joint ? sts::kModePosition : sts::kModeWheel;
  if (bus.read(id, sts::kOperatingMode, 1)[0] != mode) {
    // The mode is EEPROM: torque off, unlock, write, lock again (lerobot feetech.py disable_torque/enable_torque).
    bus.write(id, sts::kTorqueEnable, one_byte(0));
    bus.write(id, sts::kLock, one_byte(0));
    bus.write(id, sts::kOperatingMode, one_byte(mode));
    bus.write(id, sts::kLock, one_byte(1));
  }
  const auto state = bus.read(id, sts::kPresentPosition, 4);
  servo.present_ticks = decode_sign_magnitude(get_u16(state, 0), sts::kSignBit);
  servo.present_speed = decode_sign_magnitude(get_u16(state, 2), sts::kSignBit);
  servo.read_at = FeetechClock::now();
  if (joint) {
    const auto limits = bus.read(id, sts::kMinAngleLimit, 4);
    std::int32_t low = get_u16(limits, 0), high = get_u16(limits, 2);
    if (low == 0 && high == 0) high = servo.model.ticks_per_rev - 1;  // 0/0: no limits (multi-turn); one turn here
    const double a = degrees_of(servo, low), b = degrees_of(servo, high);
    servo.min_deg = std::max(servo.config.min_deg.value_or(std::min(a, b)), std::min(a, b));
    servo.max_deg = std::min(servo.config.max_deg.value_or(std::max(a, b)), std::max(a, b));
    if (servo.min_deg >= servo.max_deg)
      throw FeetechError(FeetechError::Kind::BadReply, id,
                         who(servo) + ": the configured range and the servo's min/max angle limits do not overlap");
    // Hold where it is: enabling the torque must not make the arm jump to a goal left over from before.
    servo.goal_ticks = std::clamp(*servo.present_ticks, std::min(low, high), std::max(low, high));
    servo.commanded_dps = settings_.joint_velocity_dps;
    servo.speed = joint_speed(servo, settings_.joint_velocity_dps);
    bus.write(id, sts::kCommandBlock, block(servo, servo.goal_ticks, servo.speed));
  } else {
    servo.speed = 0;
    bus.write(id, sts::kCommandBlock, block(servo, *servo.present_ticks, 0));
  }
  bus.write(id, sts::kTorqueEnable, one_byte(1));
  servo.torque_on = true;
}

void FeetechDriver::start() {
  // Shared with the job: one that outlives its deadline must not write into this stack frame.
  auto work = std::make_shared<std::vector<Servo>>();
  {
    std::lock_guard lock(mutex_);
    *work = servos_;
  }
  run(
      [this, work](FeetechBus& bus) {
        for (auto& servo : *work) init_servo(bus, servo);
      },
      std::chrono::milliseconds(2000) + settings_.reply_timeout * 20 * static_cast<int>(work->size()), "start");
  {
    std::lock_guard lock(mutex_);
    servos_ = std::move(*work);
    started_ = true;
  }
  worker_->set_idle_task([this](FeetechBus& bus) { poll(bus); },
                         std::chrono::microseconds(static_cast<long long>(1e6 / settings_.poll_hz)));
  if (log_) {
    std::string what;
    for (const auto& servo : servos_)
      what += (what.empty() ? "" : ", ") + std::to_string(servo.config.id) + " " + servo.config.name + " (" +
              std::string(servo.model.name) + ")";
    log_->info("feetech on ", settings_.port, " at ", settings_.baud_rate, " bps: ", what, "; ", fail_safe());
    if (settings_.has_wheels())
      log_->warn(
          "feetech: STS servos have no bus watchdog: if rcand dies, the wheels keep turning at their last speed; "
          "fit an e-stop that cuts the servo supply");
  }
}

void FeetechDriver::poll(FeetechBus& bus) {
  std::vector<std::uint8_t> ids;
  {
    std::lock_guard lock(mutex_);
    for (const auto& servo : servos_) ids.push_back(servo.config.id);
  }
  SyncReadResult result;
  std::string error;
  try {
    result = bus.sync_read(sts::kStatusBlock, sts::kStatusBlockLength, ids);
  } catch (const Interrupted&) {
    throw;
  } catch (const std::exception& e) {
    error = e.what();
  }
  const auto now = FeetechClock::now();
  std::vector<std::string> lost, found;
  std::lock_guard lock(mutex_);
  ++polls_;
  for (std::size_t i = 0; i < servos_.size(); ++i) {
    Servo& servo = servos_[i];
    const auto* data = i < result.data.size() && result.data[i] ? &*result.data[i] : nullptr;
    if (!data) {
      ++servo.missed_polls;
      if (servo.missed_polls >= settings_.lost_after_polls && !servo.lost) {
        servo.lost = true;
        servo.present_ticks.reset();  // where it is is unknown now: never a stale guess
        lost.push_back(who(servo) + " lost: no answer to " + std::to_string(servo.missed_polls) +
                       " status reads in a row (power, cable, ID)");
      }
      if (error.empty()) error = "no status from " + who(servo);
      continue;
    }
    if (servo.lost) found.push_back(who(servo) + " answers again");
    servo.lost = false;
    servo.missed_polls = 0;
    servo.present_ticks = decode_sign_magnitude(get_u16(*data, 0), sts::kSignBit);
    servo.present_speed = decode_sign_magnitude(get_u16(*data, 2), sts::kSignBit);
    servo.present_load = decode_sign_magnitude(get_u16(*data, 4), sts::kLoadSignBit);
    servo.voltage = (*data)[6] / 10.0;
    servo.temperature_c = (*data)[7];
    servo.read_at = now;
    servo.error = 0;
    for (const auto& [id, bits] : result.errors)
      if (id == servo.config.id) servo.error = bits;
  }
  if (!error.empty()) {
    ++poll_failures_;
    last_error_ = error;
  }
  for (const auto& text : lost) {
    last_error_ = text;
    if (log_) log_->error("feetech: ", text);
  }
  for (const auto& text : found)
    if (log_) log_->info("feetech: ", text);
}

std::int32_t FeetechDriver::hold_ticks(const Servo& servo, FeetechClock::time_point now) const {
  if (!servo.present_ticks) return servo.goal_ticks;  // no idea where it is: keep the last goal rather than guess
  // The joint kept moving since it was read: extrapolate to now, but never past the goal it was heading for.
  const double age_s = std::chrono::duration<double>(now - servo.read_at).count();
  const double ahead = static_cast<double>(*servo.present_ticks) + servo.present_speed * std::min(age_s, 0.1);
  const auto [low, high] = std::minmax(*servo.present_ticks, servo.goal_ticks);
  return std::clamp(static_cast<std::int32_t>(std::lround(ahead)), low, high);
}

void FeetechDriver::sync_command(SyncItems items, const char* what) {
  std::uint64_t generation = generation_->load();
  if (items.empty()) return;
  run(
      [items = std::move(items), generation, current = generation_](FeetechBus& bus) {
        if (current->load() == generation) bus.sync_write(sts::kCommandBlock, sts::kCommandBlockLength, items);
      },
      settings_.command_timeout, what);
}

void FeetechDriver::set_wheel_speeds(double left, double right) {
  SyncItems items;
  {
    std::lock_guard lock(mutex_);
    if (!started_) throw std::logic_error("feetech: not started");
    if (!settings_.has_wheels()) throw std::logic_error("feetech on " + settings_.port + " has no wheels (servos[].wheel)");
    for (auto& servo : servos_) {
      if (servo.config.role == FeetechServoSettings::Role::Joint) continue;
      servo.speed = wheel_speed(servo, servo.config.role == FeetechServoSettings::Role::LeftWheel ? left : right);
      items.emplace_back(servo.config.id, block(servo, servo.present_ticks.value_or(kCentreTicks), servo.speed));
    }
    ++commands_;
  }
  sync_command(std::move(items), "wheel update");
}

void FeetechDriver::set_joint_targets(const std::vector<sdk::JointTarget>& targets) {
  SyncItems items;
  {
    std::lock_guard lock(mutex_);
    if (!started_) throw std::logic_error("feetech: not started");
    // Everything is checked before anything changes: a refused command applies nothing.
    std::vector<std::pair<Servo*, const sdk::JointTarget*>> plan;
    for (const auto& target : targets) {
      auto it = std::find_if(servos_.begin(), servos_.end(), [&](const Servo& s) {
        return s.config.role == FeetechServoSettings::Role::Joint && s.config.name == target.joint;
      });
      if (it == servos_.end()) throw std::invalid_argument("joint '" + target.joint + "': not a joint of this Feetech bus");
      if (!std::isfinite(target.position_deg) || target.position_deg < it->min_deg || target.position_deg > it->max_deg)
        throw std::invalid_argument("joint '" + target.joint + "': " + std::to_string(target.position_deg) +
                                    " deg is outside the servo's range [" + std::to_string(it->min_deg) + ", " +
                                    std::to_string(it->max_deg) + "]");
      if (!std::isfinite(target.velocity_dps) || target.velocity_dps < 0)
        throw std::invalid_argument("joint '" + target.joint + "': velocity_dps must be 0 (default) or above");
      plan.emplace_back(&*it, &target);
    }
    for (auto& [servo, target] : plan) {
      double dps = target->velocity_dps > 0 ? target->velocity_dps : settings_.joint_velocity_dps;
      if (servo->config.max_velocity_dps) dps = std::min(dps, *servo->config.max_velocity_dps);
      servo->commanded_dps = dps;
      servo->speed = joint_speed(*servo, dps);
      servo->goal_ticks = ticks_of(*servo, target->position_deg);
      items.emplace_back(servo->config.id, block(*servo, servo->goal_ticks, servo->speed));
    }
    ++commands_;
  }
  sync_command(std::move(items), "joint targets");
}

void FeetechDriver::set_torque_limit(const std::string& name, double percent) {
  SyncItems items;
  {
    std::lock_guard lock(mutex_);
    if (!started_) throw std::logic_error("feetech: not started");
    if (!std::isfinite(percent) || percent <= 0 || percent > 100)
      throw std::invalid_argument("torque limit of '" + name + "': expected above 0 and at most 100 percent");
    auto it = std::find_if(servos_.begin(), servos_.end(), [&](const Servo& s) { return s.config.name == name; });
    if (it == servos_.end()) throw std::invalid_argument("'" + name + "': not a joint or wheel of this Feetech bus");
    it->torque_limit = static_cast<std::uint16_t>(std::lround(percent * 10));
    const bool joint = it->config.role == FeetechServoSettings::Role::Joint;
    items.emplace_back(it->config.id, block(*it, joint ? it->goal_ticks : it->present_ticks.value_or(kCentreTicks), it->speed));
    ++commands_;
  }
  sync_command(std::move(items), "torque limit");
}

std::vector<sdk::JointState> FeetechDriver::joint_states() const {
  std::lock_guard lock(mutex_);
  std::vector<sdk::JointState> states;
  for (const auto& servo : servos_) {
    if (servo.config.role != FeetechServoSettings::Role::Joint) continue;
    sdk::JointState state;
    state.joint = servo.config.name;
    if (started_ && servo.present_ticks) state.position_deg = degrees_of(servo, *servo.present_ticks);
    state.target_deg = started_ ? degrees_of(servo, servo.goal_ticks) : 0.0;
    state.moving = servo.present_ticks && (servo.present_speed != 0 || std::abs(*servo.present_ticks - servo.goal_ticks) > 11);
    state.velocity_dps = state.moving ? servo.commanded_dps : 0.0;
    state.torque_on = servo.torque_on;
    states.push_back(std::move(state));
  }
  return states;
}

void FeetechDriver::halt() noexcept {
  try {
    SyncItems items;
    {
      std::lock_guard lock(mutex_);
      generation_->fetch_add(1);
      ++halts_;
      if (!started_) return;
      const auto now = FeetechClock::now();
      // One block per servo, one sync write for all: joints hold where they are (their travel speed kept: a speed
      // of 0 would mean full speed), wheels to speed 0. The torque stays on.
      for (auto& servo : servos_) {
        if (servo.config.role == FeetechServoSettings::Role::Joint) {
          servo.goal_ticks = hold_ticks(servo, now);
          items.emplace_back(servo.config.id, block(servo, servo.goal_ticks, servo.speed));
        } else {
          servo.speed = 0;
          items.emplace_back(servo.config.id, block(servo, servo.present_ticks.value_or(kCentreTicks), 0));
        }
      }
    }
    const auto result = worker_->urgent(
        [items = std::move(items)](FeetechBus& bus) { bus.sync_write(sts::kCommandBlock, sts::kCommandBlockLength, items); },
        settings_.halt_deadline);
    if (result.outcome == FeetechWorker::Outcome::Done || result.outcome == FeetechWorker::Outcome::Dropped) return;
    std::string why = result.outcome == FeetechWorker::Outcome::TimedOut
                          ? "not written within " + std::to_string(settings_.halt_deadline.count()) + " ms (adapter stalled?)"
                          : "failed";
    if (result.error) try {
        std::rethrow_exception(result.error);
      } catch (const std::exception& e) {
        why += std::string(": ") + e.what();
      }
    why +=
        settings_.has_wheels() ? "; STS servos have no bus watchdog: the wheels may still turn" : "; joints keep their last goal";
    {
      std::lock_guard lock(mutex_);
      ++halts_unconfirmed_;
      last_error_ = "halt " + why;
    }
    if (log_) log_->error("feetech halt ", why);
  } catch (...) {  // allocation only
  }
}

void FeetechDriver::shutdown() noexcept { halt(); }

std::string FeetechDriver::fail_safe() const {
  std::string text =
      "fail-safe: halt = one sync write: joints hold their position with the torque on, wheels to speed 0; STS servos have "
      "no bus watchdog: if rcand dies, joints finish their last move and hold";
  if (settings_.has_wheels()) text += ", and the WHEELS KEEP TURNING at their last speed until the servo supply is cut";
  return text;
}

std::uint64_t FeetechDriver::polls() const {
  std::lock_guard lock(mutex_);
  return polls_;
}

std::string FeetechDriver::fault_locked() const {
  std::string fault;
  for (const auto& servo : servos_)
    if (servo.lost) fault += (fault.empty() ? "" : "; ") + who(servo) + " lost: no answer to its status reads";
  return fault;
}

nlohmann::json FeetechDriver::status() const {
  std::lock_guard lock(mutex_);
  json servos = json::array();
  for (const auto& servo : servos_) {
    json item{{"id", servo.config.id},
              {"name", servo.config.name},
              {"role", servo.config.role == FeetechServoSettings::Role::Joint ? "joint" : "wheel"},
              {"model", started_ ? json(std::string(servo.model.name)) : json(nullptr)},
              {"torque_on", servo.torque_on},
              {"torque_limit_pct", servo.torque_limit / 10.0},
              {"lost", servo.lost},
              {"error", servo.error ? json(std::string(first_status_text(servo.error))) : json(nullptr)}};
    if (started_ && servo.present_ticks) {
      item["load_pct"] = servo.present_load / 10.0;
      item["voltage"] = servo.voltage;
      item["temperature_c"] = servo.temperature_c;
    }
    if (started_ && servo.config.role == FeetechServoSettings::Role::Joint) {
      item["position_deg"] = servo.present_ticks ? json(degrees_of(servo, *servo.present_ticks)) : json(nullptr);
      item["target_deg"] = degrees_of(servo, servo.goal_ticks);
    } else if (started_) {
      item["speed_rpm"] = servo.present_speed * 60.0 / servo.model.ticks_per_rev;
    }
    servos.push_back(std::move(item));
  }
  json out{{"port", settings_.port},
           {"baud_rate", settings_.baud_rate},
           {"started", started_},
           {"servos", std::move(servos)},
           {"commands", commands_},
           {"polls", polls_},
           {"poll_failures", poll_failures_},
           {"halts", halts_},
           {"halts_unconfirmed", halts_unconfirmed_},
           {"last_error", last_error_.empty() ? json(nullptr) : json(last_error_)},
           {"fail_safe", fail_safe()}};
  // A lost servo: the instance runs but cannot do its job (the status board shows it as an error with this reason).
  if (const auto fault = fault_locked(); !fault.empty()) out["fault"] = fault;
  return out;
}

}  // namespace rcand::plugins::feetech
