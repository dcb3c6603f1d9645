#include "teleop.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>
#include <utility>

namespace rcand::plugins::teleop {

namespace {

using sdk::Json;
using sdk::Response;

int read_watchdog_ms(const sdk::PluginContext& ctx) {
  std::string key = "watchdog_ms";
  auto value = ctx.config().get<long long>(key);
  if (!value) {
    key = "safety.watchdog_ms";
    value = ctx.robot_config().get<long long>(key);
  }
  const long long ms = value.value_or(500);
  if (ms < 1 || ms > Teleop::kMaxDurationMs)
    throw sdk::ConfigError(key + ": expected an integer in [1, " + std::to_string(Teleop::kMaxDurationMs) + "], found " +
                           std::to_string(ms));
  return static_cast<int>(ms);
}

double read_max_linear(const sdk::PluginContext& ctx) {
  const double max = ctx.robot_config().get<double>("safety.max_linear_speed").value_or(1.0);
  if (!std::isfinite(max) || max < 0.0)
    throw sdk::ConfigError("safety.max_linear_speed: expected a number >= 0, found " + std::to_string(max));
  return std::min(max, 1.0);  // wheel speeds are fractions of full speed
}

std::string limit_text(double limit) {
  std::ostringstream text;  // the shortest spelling: 1 and 0.4, not 1.000000
  text << "[-" << limit << ", " << limit << "]";
  return text.str();
}

// A finite number in [-limit, limit]; nullopt and `out` set (left as it is when absent), or the 400 naming the field.
// Out of range is refused, never clamped: a client that asks for 5x full speed has a bug, and driving it at full speed
// hides it.
std::optional<Response> read_number(const Json& body, const char* field, double limit, const char* limit_source,
                                    double& out) {
  const std::string range = limit_text(limit);
  const auto it = body.find(field);
  if (it == body.end()) return std::nullopt;
  if (!it->is_number())
    return Response::bad_request(field, std::string(field) + " must be a number in " + range + ", found " + it->type_name());
  out = it->get<double>();
  if (!std::isfinite(out) || out < -limit || out > limit)
    return Response::bad_request(field, std::string(field) + " must be a number in " + range + limit_source + ", found " +
                                            it->dump());
  return std::nullopt;
}

// Optional duration_ms: an integer in [1, 60000].
std::optional<Response> read_duration(const Json& body, std::optional<int>& out) {
  const auto it = body.find("duration_ms");
  if (it == body.end()) return std::nullopt;
  const std::string expected = "duration_ms must be an integer in [1, " + std::to_string(Teleop::kMaxDurationMs) + "]";
  if (!it->is_number_integer()) return Response::bad_request("duration_ms", expected + ", found " + it->type_name());
  const double ms = it->get<double>();  // as double: no wrap-around for huge unsigned values
  if (ms < 1 || ms > Teleop::kMaxDurationMs) return Response::bad_request("duration_ms", expected + ", found " + it->dump());
  out = static_cast<int>(ms);
  return std::nullopt;
}

Response no_driver() {
  return Response::error(503, "UNAVAILABLE", "teleop: no differential_drive actuator is configured");
}

}  // namespace

WheelMix mix(double linear, double angular) noexcept {
  double left = linear - angular;
  double right = linear + angular;
  const double scale = std::max({1.0, std::abs(left), std::abs(right)});
  return {left / scale, right / scale};
}

Teleop::Teleop(sdk::PluginContext& ctx)
    : ctx_(ctx),
      worker_(ctx.worker("motion")),
      watchdog_ms_(read_watchdog_ms(ctx)),
      max_linear_(read_max_linear(ctx)),
      configured_driver_(ctx.config().get<std::string>("driver")),
      obstacles_(ctx) {}

std::vector<sdk::Route> Teleop::routes() {
  return {
      {"POST", "/api/action", sdk::Scope::Control, true, "move", [this](const sdk::Request& r) { return move(r); }},
      {"POST", "/api/action", sdk::Scope::Control, false, "stop", [this](const sdk::Request& r) { return stop(r); }},
  };
}

std::optional<std::string> Teleop::resolve_driver() const {
  if (configured_driver_) return configured_driver_;
  return ctx_.motion().first_actuator(sdk::DifferentialDrive::kInterface);
}

Response Teleop::move(const sdk::Request& request) {
  if (!request.body.is_object()) return Response::bad_request("body", "the body must be a JSON object");
  // A move names linear, angular or both; the one left out is 0 (a pure turn, a straight line).
  if (!request.body.contains("linear") && !request.body.contains("angular"))
    return Response::bad_request("linear", "a move needs linear or angular (the missing one is 0): numbers in " +
                                               limit_text(max_linear_) + " and " + limit_text(1.0));
  double linear = 0.0, angular = 0.0;
  std::optional<int> duration_ms;
  const char* linear_source = max_linear_ < 1.0 ? " (safety.max_linear_speed)" : "";
  if (auto bad = read_number(request.body, "linear", max_linear_, linear_source, linear)) return *bad;
  if (auto bad = read_number(request.body, "angular", 1.0, "", angular)) return *bad;
  if (auto bad = read_duration(request.body, duration_ms)) return *bad;
  const WheelMix wheels = mix(linear, angular);

  const auto driver = resolve_driver();
  if (!driver) return no_driver();

  // Forward only (see teleop.hpp). As nav: an obstacle latches the e-stop; depth that cannot be read latches when
  // the robot is already moving (a refreshed dead-man), and otherwise refuses the move without latching (503: the
  // robot stands still, and 423 would claim a latch that is not there).
  const bool forward = linear > 0.0;
  if (forward) {
    const obstacle::Verdict verdict = obstacles_.check(ctx_);
    if (!verdict.clear()) {
      bool moving = false;
      {
        std::lock_guard state(state_mutex_);
        moving = moving_;
      }
      if (verdict.kind == obstacle::Verdict::Kind::Obstacle || moving) {
        obstacle::Guard::latch(ctx_, "teleop", verdict, moving);
        const bool blocked = verdict.kind == obstacle::Verdict::Kind::Obstacle;
        return Response::error(423, "ESTOP_ACTIVE", "teleop: " + verdict.why + "; the e-stop is latched",
                               {{"reason", blocked ? "obstacle" : "depth_unavailable"}});
      }
      return Response::error(503, "UNAVAILABLE", "teleop: " + verdict.why + "; the move was not made",
                             {{"reason", "depth_unavailable"}});
    }
  }

  std::lock_guard motion(motion_mutex_);
  const std::uint64_t generation = ++generation_;
  {
    std::lock_guard state(state_mutex_);
    if (timer_) worker_.cancel(*timer_);  // if this loses the race, the generation check stops the old timer
    timer_.reset();
    if (watch_timer_) worker_.cancel(*watch_timer_);
    watch_timer_.reset();
  }
  const sdk::GateStatus gate = ctx_.motion().actuate_as<sdk::DifferentialDrive>(
      *driver, [&](sdk::DifferentialDrive& drive) { drive.set_wheel_speeds(wheels.left, wheels.right); });
  if (gate != sdk::GateStatus::Ok) {
    {
      std::lock_guard state(state_mutex_);
      moving_ = false;
    }
    publish();
    return sdk::gate_refusal(gate, *driver);
  }
  // The e-stop landed while the command ran: the gate halted the wheels again, so this move did not happen.
  if (generation_ != generation) return sdk::gate_refusal(sdk::GateStatus::EstopActive, *driver);

  const int stop_after_ms = duration_ms.value_or(watchdog_ms_);
  const sdk::TimerId timer = worker_.schedule(std::chrono::milliseconds(stop_after_ms),
                                              [this, generation, id = *driver] { expire(generation, id); });
  std::optional<sdk::TimerId> watch_timer;
  if (forward && obstacles_.in_play(ctx_))
    watch_timer = worker_.schedule(obstacle::kCheckPeriod, [this, generation] { watch(generation); });
  {
    std::lock_guard state(state_mutex_);
    if (generation_ == generation) {
      timer_ = timer;
      watch_timer_ = watch_timer;
      moving_ = true;
    } else {  // on_estop ran in between; the timers are stale anyway
      worker_.cancel(timer);
      if (watch_timer) worker_.cancel(*watch_timer);
    }
    last_command_us_ = ctx_.clock().now_us();
    last_driver_ = *driver;
  }
  publish();
  return Response::ok({{"ok", true},
                       {"type", "move"},
                       {"linear", linear},
                       {"angular", angular},
                       {"left", wheels.left},
                       {"right", wheels.right},
                       {"duration_ms", duration_ms ? Json(*duration_ms) : Json(nullptr)},
                       {"deadman_ms", duration_ms ? Json(nullptr) : Json(watchdog_ms_)}});
}

Response Teleop::stop(const sdk::Request&) {
  const auto driver = resolve_driver();
  if (!driver) return no_driver();
  disarm();
  ctx_.motion().halt(*driver);
  return Response::ok({{"ok", true}, {"type", "stop"}});
}

void Teleop::expire(std::uint64_t generation, const std::string& driver) noexcept {
  std::lock_guard motion(motion_mutex_);
  if (generation_ != generation) return;  // a newer move, a stop or the e-stop owns the wheels now
  ctx_.motion().halt(driver);
  {
    std::lock_guard state(state_mutex_);
    if (generation_ == generation) {
      timer_.reset();
      if (watch_timer_) worker_.cancel(*watch_timer_);
      watch_timer_.reset();
      moving_ = false;
    }
  }
  publish();
}

// A forward move's obstacle check. It never takes motion_mutex_: the e-stop it may request halts the drivers, and
// must not queue behind a move in progress.
void Teleop::watch(std::uint64_t generation) noexcept {
  {
    std::lock_guard state(state_mutex_);
    // A newer move, a stop or the e-stop owns the wheels now, or the move ended: a still robot is not checked.
    if (generation_ != generation || !moving_) return;
  }
  obstacle::Verdict verdict;
  bool clear = false;
  try {
    verdict = obstacles_.check(ctx_);
    clear = verdict.clear();
  } catch (...) {  // no memory for the verdict's words: cannot tell, so not clear
  }
  if (!clear) {
    obstacle::Guard::latch(ctx_, "teleop", verdict, true);  // on_estop() disarms the move and this watch
    return;
  }
  try {
    const sdk::TimerId next = worker_.schedule(obstacle::kCheckPeriod, [this, generation] { watch(generation); });
    std::lock_guard state(state_mutex_);
    if (generation_ == generation) watch_timer_ = next;
    else worker_.cancel(next);
  } catch (...) {  // cannot keep watching a moving robot: stop it rather than drive on unchecked
    ctx_.estop().request_estop("teleop: the obstacle check could not be rescheduled while moving");
  }
}

void Teleop::disarm() noexcept {
  ++generation_;
  {
    std::lock_guard state(state_mutex_);
    if (timer_) worker_.cancel(*timer_);
    timer_.reset();
    if (watch_timer_) worker_.cancel(*watch_timer_);
    watch_timer_.reset();
    moving_ = false;
  }
  publish();
}

void Teleop::publish() noexcept {
  try {
    std::lock_guard order(publish_mutex_);
    ctx_.publish_status(status());
  } catch (...) {  // no memory for the status: the kernel asks status() itself a second later
  }
}

void Teleop::on_estop() noexcept { disarm(); }

void Teleop::shutdown() noexcept { disarm(); }

sdk::Json Teleop::status() const {
  std::optional<std::string> driver;
  try {
    driver = resolve_driver();
  } catch (...) {  // status never throws; an unknown driver shows as null
  }
  std::lock_guard state(state_mutex_);
  return {{"driver", driver ? Json(*driver) : Json(nullptr)},
          {"moving", moving_},
          {"last_command_us", last_command_us_ ? Json(*last_command_us_) : Json(nullptr)}};
}

}  // namespace rcand::plugins::teleop
