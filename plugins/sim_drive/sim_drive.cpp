#include "sim_drive.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <thread>

namespace rcand::plugins::sim_drive {

namespace {

double positive_setting(const sdk::PluginContext& ctx, const char* key, double fallback) {
  const std::string physics_key = std::string("physics.") + key;
  double value = fallback;
  std::string source = key;
  if (auto own = ctx.config().get<double>(key)) value = *own;
  else if (auto physics = ctx.robot_config().get<double>(physics_key)) value = *physics, source = physics_key;
  if (!std::isfinite(value) || value <= 0.0)
    throw sdk::ConfigError(source + ": expected a number > 0, found " + std::to_string(value));
  return value;
}

int bounded_int(const sdk::PluginContext& ctx, const char* key, int max) {
  const auto value = ctx.config().get<long long>(key).value_or(0);
  if (value < 0 || value > max)
    throw sdk::ConfigError(std::string(key) + ": expected an integer in [0, " + std::to_string(max) + "], found " +
                           std::to_string(value));
  return static_cast<int>(value);
}

double clamp_unit(double v) { return std::isfinite(v) ? std::clamp(v, -1.0, 1.0) : 0.0; }

}  // namespace

SimDriveSettings SimDriveSettings::from(const sdk::PluginContext& ctx) {
  SimDriveSettings s;
  s.max_wheel_rps = positive_setting(ctx, "max_wheel_rps", s.max_wheel_rps);
  s.wheel_circumference_m = positive_setting(ctx, "wheel_circumference_m", s.wheel_circumference_m);
  s.wheel_base_m = positive_setting(ctx, "wheel_base_m", s.wheel_base_m);
  s.fail_after_commands = bounded_int(ctx, "fail_after_commands", 1'000'000'000);
  s.halt_delay_ms = bounded_int(ctx, "halt_delay_ms", 10'000);
  return s;
}

double SimDrive::Pose::heading_deg() const {
  double deg = std::remainder(heading_rad * 180.0 / std::numbers::pi, 360.0);  // [-180, 180]
  if (deg <= -180.0) deg += 360.0;
  return deg == 0.0 ? 0.0 : deg;  // no "-0" in status
}

SimDrive::SimDrive(const sdk::Clock& clock, SimDriveSettings settings, sdk::PluginContext* publish_to)
    : clock_(clock),
      settings_(settings),
      pose_us_(clock.now_us()),
      zero_since_us_(pose_us_),
      publisher_(
          publish_to, kPublishPeriod,
          [this] {
            std::lock_guard lock(mutex_);
            return sdk::StatusPublisher::Snapshot{status_locked(false), changes_, left_ != 0.0 || right_ != 0.0};
          },
          [this] {
            std::lock_guard lock(mutex_);
            return changes_;
          }) {}

void SimDrive::set_wheel_speeds(double left, double right) {
  {
    std::lock_guard lock(mutex_);
    ++attempts_;
    if (settings_.fail_after_commands > 0 && attempts_ >= static_cast<std::uint64_t>(settings_.fail_after_commands))
      throw std::runtime_error("sim_diff_drive: injected failure on command " + std::to_string(attempts_) +
                               " (fail_after_commands=" + std::to_string(settings_.fail_after_commands) + ")");
    ++commands_;
    apply(clamp_unit(left), clamp_unit(right), "command");
  }
  publisher_.changed();
}

void SimDrive::halt() noexcept {
  // The drill delay is outside the lock, so status() stays answerable while a slow halt is in progress.
  if (settings_.halt_delay_ms > 0) std::this_thread::sleep_for(std::chrono::milliseconds(settings_.halt_delay_ms));
  std::lock_guard lock(mutex_);
  ++halts_;
  try {
    apply(0.0, 0.0, "halt");
  } catch (...) {  // only allocation can fail here; the wheels are zeroed before the event is recorded
  }
}

void SimDrive::apply(double left, double right, const char* cause) {
  const std::int64_t now = clock_.now_us();
  pose_ = pose_at(now);
  pose_us_ = std::max(pose_us_, now);
  const bool was_zero = left_ == 0.0 && right_ == 0.0;
  left_ = left;
  right_ = right;
  if (left == 0.0 && right == 0.0) {
    if (!was_zero) zero_since_us_ = now;
  }
  timeline_.push_back({now, left, right, cause});
  while (timeline_.size() > kTimelineCapacity) timeline_.pop_front();
  ++changes_;
}

SimDrive::Pose SimDrive::pose_at(std::int64_t now_us) const {
  const double dt = static_cast<double>(std::max<std::int64_t>(0, now_us - pose_us_)) / 1e6;
  if (dt == 0.0 || (left_ == 0.0 && right_ == 0.0)) return pose_;
  const double metres_per_s = settings_.max_wheel_rps * settings_.wheel_circumference_m;
  const double v_left = left_ * metres_per_s;
  const double v_right = right_ * metres_per_s;
  const double v = (v_left + v_right) / 2.0;
  const double omega = (v_right - v_left) / settings_.wheel_base_m;  // rad/s, counter-clockwise positive
  Pose next = pose_;
  const double theta = pose_.heading_rad;
  if (std::abs(omega) < 1e-12) {
    next.x_m += v * std::cos(theta) * dt;
    next.y_m += v * std::sin(theta) * dt;
  } else {  // exact arc for constant wheel speeds
    next.heading_rad = theta + omega * dt;
    next.x_m += v / omega * (std::sin(next.heading_rad) - std::sin(theta));
    next.y_m -= v / omega * (std::cos(next.heading_rad) - std::cos(theta));
  }
  return next;
}

nlohmann::json SimDrive::status() const {
  std::lock_guard lock(mutex_);
  return status_locked(true);
}

nlohmann::json SimDrive::status_locked(bool with_timeline) const {
  const std::int64_t now = clock_.now_us();
  const Pose pose = pose_at(now);
  const bool moving = left_ != 0.0 || right_ != 0.0;
  nlohmann::json status{{"left", left_}, {"right", right_}, {"moving", moving},
                        {"now_us", now}, {"halts", halts_}, {"commands", commands_}};
  status["pose"] = {{"x_m", pose.x_m}, {"y_m", pose.y_m}, {"heading_deg", pose.heading_deg()}};
  status["zero_since_us"] = moving ? nlohmann::json(nullptr) : nlohmann::json(zero_since_us_);
  if (!with_timeline) return status;
  nlohmann::json& events = status["timeline"] = nlohmann::json::array();
  const std::size_t first = timeline_.size() > kStatusEvents ? timeline_.size() - kStatusEvents : 0;
  for (std::size_t i = first; i < timeline_.size(); ++i) {
    const Event& e = timeline_[i];
    events.push_back({{"t_us", e.t_us}, {"left", e.left}, {"right", e.right}, {"cause", e.cause}});
  }
  return status;
}

SimDrive::Pose SimDrive::pose() const {
  std::lock_guard lock(mutex_);
  return pose_at(clock_.now_us());
}
std::vector<SimDrive::Event> SimDrive::timeline() const {
  std::lock_guard lock(mutex_);
  return {timeline_.begin(), timeline_.end()};
}
double SimDrive::left() const {
  std::lock_guard lock(mutex_);
  return left_;
}
double SimDrive::right() const {
  std::lock_guard lock(mutex_);
  return right_;
}
std::uint64_t SimDrive::commands() const {
  std::lock_guard lock(mutex_);
  return commands_;
}
std::uint64_t SimDrive::halts() const {
  std::lock_guard lock(mutex_);
  return halts_;
}

}  // namespace rcand::plugins::sim_drive
