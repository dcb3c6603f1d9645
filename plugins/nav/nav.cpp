#include "nav.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <utility>

namespace rcand::plugins::nav {

namespace {

using sdk::Json;
using sdk::Response;

constexpr std::int64_t kDefaultMaxJobMs = 600'000;  // 10 minutes of dead reckoning is already far beyond its accuracy

std::int64_t read_max_job_us(const sdk::PluginContext& ctx) {
  const long long ms = ctx.config().get<long long>("max_job_ms").value_or(kDefaultMaxJobMs);
  if (ms < 1 || ms > 86'400'000)
    throw sdk::ConfigError("max_job_ms: expected an integer in [1, 86400000], found " + std::to_string(ms));
  return ms * 1000;
}

Json or_null(const std::optional<std::string>& value) { return value ? Json(*value) : Json(nullptr); }

}  // namespace

Nav::Nav(sdk::PluginContext& ctx, Sleeper sleeper)
    : ctx_(ctx),
      worker_(ctx.worker("job")),
      physics_(Physics::from(ctx.robot_config())),
      configured_driver_(ctx.config().get<std::string>("driver")),
      max_job_us_(read_max_job_us(ctx)),
      obstacles_(ctx),
      sleeper_(std::move(sleeper)) {
  if (!sleeper_) {
    sleeper_ = [this](std::chrono::microseconds slice, const std::function<bool()>& woken) {
      std::unique_lock lock(wake_mutex_);
      wake_cv_.wait_for(lock, slice, woken);
    };
  }
  if (sdk::find<sdk::ObstacleSource>(ctx_) != nullptr && !obstacles_.min_cm())
    ctx_.log().warn("an obstacle source is present but neither agent.min_obstacle_m nor safety.obstacle_stop_cm is set: "
                    "nav will not stop for obstacles");
}

// Offered once nav can answer; the kernel withdraws both before shutdown(). Refused only when another instance
// offers them already (a second nav-like capability), which the kernel logs.
void Nav::start() {
  sdk::offer<sdk::PoseSource>(ctx_, *this);
  sdk::offer<sdk::TripEstimator>(ctx_, trips_);
}

std::vector<sdk::Route> Nav::routes() {
  return {
      {"POST", "/api/nav/waypoint", sdk::Scope::Control, true, "", [this](const sdk::Request& r) { return waypoint(r); }},
      // A stop is never refused by the e-stop (docs/protocol.md §7: a non-latching stop of the running job).
      {"POST", "/api/nav/cancel", sdk::Scope::Control, false, "", [this](const sdk::Request& r) { return cancel(r); }},
      {"GET", "/api/nav/status", sdk::Scope::Status, false, "", [this](const sdk::Request& r) { return get_status(r); }},
  };
}

std::optional<std::string> Nav::resolve_driver() const {
  if (configured_driver_) return configured_driver_;
  return ctx_.motion().first_actuator(sdk::DifferentialDrive::kInterface);
}

std::string Nav::new_job_id() {
  static thread_local std::mt19937 random{std::random_device{}()};
  char text[16];
  std::snprintf(text, sizeof text, "nav-%06x", static_cast<unsigned>((random() + ++job_counter_) & 0xffffffu));
  return text;
}

// ---- the handlers (capability worker) -------------------------------------------------------------------------

Response Nav::waypoint(const sdk::Request& request) {
  auto planned = plan_waypoint(request.body, physics_, max_job_us_);
  if (auto* bad = std::get_if<Response>(&planned)) return *bad;
  const Plan plan = std::get<Plan>(planned);

  const auto driver = resolve_driver();
  if (!driver) return Response::error(503, "UNAVAILABLE", "nav: no differential_drive actuator is configured");
  {
    std::lock_guard lock(mutex_);
    if (running_)
      return Response::error(409, "NAV_BUSY", "a nav job is running; cancel it with POST /api/nav/cancel or wait",
                             {{"job_id", job_->id}});
  }
  // Can it start at all? Nothing has moved yet.
  if (ctx_.estop().latched()) return sdk::gate_refusal(sdk::GateStatus::EstopActive, *driver);
  const auto health = ctx_.motion().inspect(*driver, [](const sdk::ActuatorDriver&) {});
  if (health != sdk::GateStatus::Ok) return sdk::gate_refusal(health, *driver);
  if (auto stop = obstacle_stop(false)) {
    if (stop->kind == obstacle::Verdict::Kind::Obstacle)
      return Response::error(423, "ESTOP_ACTIVE", "nav: " + stop->why + "; the e-stop is latched", {{"reason", "obstacle"}});
    // Depth that cannot be read refuses the job but latches nothing: the robot stands still, which is safe, and
    // the cause is usually passing (the depth camera warming up or reconnecting). 503, not 423: 423 says the
    // e-stop is latched (docs/protocol.md §6.6), and it is not.
    return Response::error(503, "UNAVAILABLE", "nav: " + stop->why + "; the job was not started",
                           {{"reason", "depth_unavailable"}});
  }

  const std::uint64_t estop_events = estop_events_.load();
  cancel_requested_ = false;
  const std::string id = new_job_id();
  const bool turning = plan.turn_us > 0;
  {
    std::lock_guard lock(mutex_);
    running_ = true;
    job_ = Job{id, plan, *driver, turning ? "turning" : "driving", ctx_.clock().now_us(), 0, 0, Json(nullptr), false, 0.0, 0.0};
    job_->phase_started_us = job_->started_us;
  }
  Json answer{{"ok", true}, {"job_id", id}, {"eta_ms", plan.eta_ms()}, {"turn_ms", plan.turn_us / 1000.0},
              {"drive_ms", plan.drive_us / 1000.0}};
  if (plan.turn_us == 0 && plan.drive_us == 0) {  // nothing to do: done at once, no wheel command
    finish(true, "completed", "nothing to do");
    answer["started_us"] = nullptr;
    return Response::ok(std::move(answer));
  }

  // The first phase starts here, so a job that cannot start answers 423/503 with the motors at zero.
  const auto refused = turning ? command(*driver, plan.turn_left(), plan.turn_right(), estop_events)
                               : command(*driver, plan.drive_wheels(), plan.drive_wheels(), estop_events);
  if (refused) {
    ctx_.motion().halt(*driver);
    finish(false, refused->reason, refused->message);
    return sdk::gate_refusal(refused->gate, *driver);
  }
  const std::int64_t started = ctx_.clock().now_us();
  {
    std::lock_guard lock(mutex_);
    job_->started_us = job_->phase_started_us = started;
    job_->phase_open = true;
  }
  publish();  // before the job runs: its own publishes (the last one at its end) come after this one
  try {
    worker_.post([this, estop_events] { run_job(estop_events); });
  } catch (const std::exception& e) {  // the job cannot run: stop what the handler started
    ctx_.motion().halt(*driver);
    finish(false, "error", std::string("could not start the job: ") + e.what());
    return Response::error(503, "UNAVAILABLE", std::string("nav: could not start the job: ") + e.what());
  }
  ctx_.log().info("job ", id, ": turn ", plan.waypoint.heading_deg, " deg, drive ", plan.waypoint.distance_m, " m at speed ",
                  plan.waypoint.speed, " (eta ", plan.eta_ms(), " ms)");
  answer["started_us"] = started;
  return Response::ok(std::move(answer));
}

Response Nav::cancel(const sdk::Request&) {
  std::string id, driver;
  {
    std::lock_guard lock(mutex_);
    if (!running_)
      return Response::ok({{"ok", true}, {"cancelled", false}, {"job_id", job_ ? Json(job_->id) : Json(nullptr)},
                           {"state", job_ ? Json(job_->state) : Json("idle")}});
    id = job_->id;
    driver = job_->driver;
  }
  const std::int64_t received = ctx_.clock().now_us();
  cancel_requested_ = true;
  {
    // The motors stop here, not when the job notices: a job between phases holds motion_mutex_ only for one
    // command, and sees cancel_requested_ before its next one.
    std::lock_guard lock(motion_mutex_);
    ctx_.motion().halt(driver);
  }
  const std::int64_t halted = ctx_.clock().now_us();
  wake();
  std::unique_lock lock(mutex_);
  ended_cv_.wait_for(lock, kCancelWait, [this] { return !running_; });
  return Response::ok({{"ok", true},
                       {"cancelled", true},
                       {"job_id", id},
                       {"received_us", received},
                       {"halted_us", halted},
                       {"state", job_->state},
                       {"result", job_->result}});
}

Response Nav::get_status(const sdk::Request&) const { return Response::ok(status()); }

// ---- the job (the "job" worker) ---------------------------------------------------------------------------------

std::optional<Nav::Refusal> Nav::command(const std::string& driver, double left, double right, std::uint64_t estop_events) {
  std::lock_guard lock(motion_mutex_);
  if (shutting_down_) return Refusal{sdk::GateStatus::Ok, "shutdown", "rcand is shutting down"};
  if (cancel_requested_) return Refusal{sdk::GateStatus::Ok, "cancelled", "cancelled by POST /api/nav/cancel"};
  if (interrupted(estop_events)) return Refusal{sdk::GateStatus::EstopActive, "estop", "the e-stop latched"};
  const auto gate = ctx_.motion().actuate_as<sdk::DifferentialDrive>(
      driver, [&](sdk::DifferentialDrive& drive) { drive.set_wheel_speeds(left, right); });
  switch (gate) {
    case sdk::GateStatus::Ok: return std::nullopt;
    case sdk::GateStatus::EstopActive: return Refusal{gate, "estop", "the e-stop latched"};
    case sdk::GateStatus::ActuatorFailed:
      return Refusal{gate, "actuator_failed", "actuator '" + driver + "' failed and is out of service"};
    default: return Refusal{gate, "actuator_unavailable", "actuator '" + driver + "' is not a usable differential drive"};
  }
}

void Nav::run_job(std::uint64_t estop_events) noexcept {
  std::string driver;
  Plan plan;
  {
    std::lock_guard lock(mutex_);
    if (!job_ || !running_) return;
    driver = job_->driver;
    plan = job_->plan;
  }
  bool ok = true;
  std::string reason = "completed", message = "arrived (dead reckoning)";
  auto abort = [&](std::string why, std::string text) {
    ok = false;
    reason = std::move(why);
    message = std::move(text);
  };
  // The seed's "finally" (§10.4): whatever ends the job, the motors stop, then the job is recorded as ended.
  struct StopGuard {
    Nav& nav;
    const std::string& driver;
    bool& ok;
    std::string& reason;
    std::string& message;
    ~StopGuard() {
      nav.ctx_.motion().halt(driver);
      const std::int64_t stopped = nav.ctx_.clock().now_us();
      {
        std::lock_guard lock(nav.mutex_);
        nav.commit_phase(stopped);
      }
      nav.finish(ok, reason, message);
    }
  } guard{*this, driver, ok, reason, message};

  auto phase_end_text = [](End end) {
    switch (end) {
      case End::Cancelled: return std::pair<std::string, std::string>{"cancelled", "cancelled by POST /api/nav/cancel"};
      case End::Estop: return std::pair<std::string, std::string>{"estop", "the e-stop latched"};
      case End::Shutdown: return std::pair<std::string, std::string>{"shutdown", "rcand is shutting down"};
      default: return std::pair<std::string, std::string>{"error", "unexpected end"};
    }
  };
  try {
    std::int64_t phase_start = 0;
    bool turning = false;
    {
      std::lock_guard lock(mutex_);
      phase_start = job_->phase_started_us;
      turning = job_->state == "turning";
    }
    for (;;) {
      const std::int64_t length = turning ? plan.turn_us : plan.drive_us;
      const End end = wait_until(phase_start + length, estop_events);
      if (end == End::Obstacle) {
        const bool blocked = obstacle_stopped_.kind == obstacle::Verdict::Kind::Obstacle;
        abort(blocked ? "obstacle" : "depth_unavailable", obstacle_stopped_.why + "; the e-stop is latched");
        return;
      }
      if (end != End::Elapsed) {
        auto [why, text] = phase_end_text(end);
        abort(why, text + (turning ? " mid-turn" : " mid-drive"));
        return;
      }
      if (!turning || plan.drive_us == 0) return;  // completed

      // Turn done: drive. The wheels switch directly from turning to driving (no stop in between).
      const auto refused = command(driver, plan.drive_wheels(), plan.drive_wheels(), estop_events);
      const std::int64_t now = ctx_.clock().now_us();
      {
        std::lock_guard lock(mutex_);
        commit_phase(now);
        if (!refused) {
          job_->state = "driving";
          job_->phase_started_us = now;
          job_->phase_open = true;
        }
      }
      if (refused) {
        abort(refused->reason, refused->message + " before the drive");
        return;
      }
      publish();
      phase_start = now;
      turning = false;
    }
  } catch (const std::exception& e) {
    abort("error", std::string("the job failed: ") + e.what());
  } catch (...) {
    abort("error", "the job failed with a non-standard exception");
  }
}

Nav::End Nav::wait_until(std::int64_t deadline_us, std::uint64_t estop_events) {
  const auto period_us = std::chrono::duration_cast<std::chrono::microseconds>(kObstaclePeriod).count();
  std::int64_t& last_check = last_obstacle_check_us_;  // carried across phases: checks stay <= kObstaclePeriod apart
  auto woken = [this, estop_events] { return cancel_requested_ || shutting_down_ || interrupted(estop_events); };
  for (;;) {
    if (shutting_down_) return End::Shutdown;
    if (cancel_requested_) return End::Cancelled;
    if (interrupted(estop_events)) return End::Estop;
    const std::int64_t now = ctx_.clock().now_us();
    if (now >= deadline_us) return End::Elapsed;
    if (now - last_check >= period_us) {
      if (auto stop = obstacle_stop(true)) {
        obstacle_stopped_ = std::move(*stop);
        return End::Obstacle;
      }
    }
    if (now - last_publish_us_.load() >= std::chrono::microseconds(kPublishPeriod).count()) publish();  // the pose moves
    const std::int64_t slice = std::max<std::int64_t>(1, std::min(deadline_us - now, last_check + period_us - now));
    sleeper_(std::chrono::microseconds(slice), woken);
  }
}

std::optional<obstacle::Verdict> Nav::obstacle_stop(bool moving) {
  last_obstacle_check_us_ = ctx_.clock().now_us();
  obstacle::Verdict verdict = obstacles_.check(ctx_);
  if (verdict.clear()) return std::nullopt;
  if (moving || verdict.kind == obstacle::Verdict::Kind::Obstacle) obstacle::Guard::latch(ctx_, "nav", verdict, moving);
  else ctx_.log().warn(verdict.why, ": the job is refused");
  return verdict;
}

bool Nav::interrupted(std::uint64_t estop_events) const noexcept {
  return estop_events_.load() != estop_events || ctx_.estop().latched();
}

void Nav::wake() noexcept {
  { std::lock_guard lock(wake_mutex_); }  // a waiter between its predicate check and its wait cannot miss this
  wake_cv_.notify_all();
}

// ---- bookkeeping ------------------------------------------------------------------------------------------------

void Nav::commit_phase(std::int64_t until_us) {
  if (!job_ || !job_->phase_open) return;
  job_->phase_open = false;
  const double seconds = static_cast<double>(std::max<std::int64_t>(0, until_us - job_->phase_started_us)) / 1e6;
  const Waypoint& w = job_->plan.waypoint;
  if (job_->state == "turning") {
    const double degrees = std::min(seconds * physics_.degrees_per_s(w.speed), std::abs(w.heading_deg));
    const double signed_degrees = std::copysign(degrees, w.heading_deg);
    pose_ = pose_.turned(signed_degrees);
    job_->turned_deg += signed_degrees;
  } else if (job_->state == "driving") {
    const double metres = std::min(seconds * physics_.metres_per_s(w.speed), std::abs(w.distance_m));
    const double signed_metres = std::copysign(metres, w.distance_m);
    pose_ = pose_.driven(signed_metres);
    job_->driven_m += signed_metres;
  }
}

Pose Nav::live_pose(std::int64_t now_us) const {
  if (!job_ || !job_->phase_open) return pose_;
  const double seconds = static_cast<double>(std::max<std::int64_t>(0, now_us - job_->phase_started_us)) / 1e6;
  const Waypoint& w = job_->plan.waypoint;
  if (job_->state == "turning")
    return pose_.turned(std::copysign(std::min(seconds * physics_.degrees_per_s(w.speed), std::abs(w.heading_deg)), w.heading_deg));
  return pose_.driven(std::copysign(std::min(seconds * physics_.metres_per_s(w.speed), std::abs(w.distance_m)), w.distance_m));
}

void Nav::finish(bool ok, const std::string& reason, const std::string& message) {
  std::string id;
  {
    std::lock_guard lock(mutex_);
    if (!job_ || !running_) return;
    job_->phase_open = false;
    job_->ended_us = ctx_.clock().now_us();
    job_->state = ok ? "done" : "aborted";
    job_->result = {{"ok", ok},
                    {"reason", reason},
                    {"message", message},
                    {"turned_deg", job_->turned_deg},
                    {"driven_m", job_->driven_m},
                    {"ended_us", job_->ended_us}};
    running_ = false;
    id = job_->id;
  }
  ended_cv_.notify_all();
  publish();
  if (ok) ctx_.log().info("job ", id, " done: ", message);
  else ctx_.log().warn("job ", id, " aborted (", reason, "): ", message);
}

void Nav::publish() noexcept {
  last_publish_us_ = ctx_.clock().now_us();
  try {
    ctx_.publish_status(status());
  } catch (...) {  // no memory for the status: the kernel asks status() itself a second later
  }
}

// ---- status (I/O thread) ----------------------------------------------------------------------------------------

sdk::Json Nav::status() const {
  const std::int64_t now = ctx_.clock().now_us();
  std::lock_guard lock(mutex_);
  const Pose pose = live_pose(now);
  Json doc{{"running", running_},
           {"job_id", nullptr},
           {"state", "idle"},
           {"distance_m", nullptr},
           {"heading_deg", nullptr},
           {"speed", nullptr},
           {"elapsed_ms", nullptr},
           {"eta_ms", nullptr},
           {"result", nullptr},
           {"pose", {{"x_m", pose.x_m}, {"y_m", pose.y_m}, {"heading_deg", pose.heading_deg}}},
           {"driver", or_null(configured_driver_)}};
  if (job_) {
    const Waypoint& w = job_->plan.waypoint;
    doc["job_id"] = job_->id;
    doc["state"] = job_->state;
    doc["distance_m"] = w.distance_m;
    doc["heading_deg"] = w.heading_deg;
    doc["speed"] = w.speed;
    doc["elapsed_ms"] = ((running_ ? now : job_->ended_us) - job_->started_us) / 1000;
    doc["eta_ms"] = job_->plan.eta_ms();
    doc["result"] = job_->result;
    doc["driver"] = job_->driver;
  }
  return doc;
}

sdk::PoseReading Nav::read() const noexcept {
  const std::int64_t now = ctx_.clock().now_us();
  std::lock_guard lock(mutex_);
  const Pose pose = live_pose(now);
  return {true, {pose.x_m, pose.y_m, pose.heading_deg}, running_};
}

void Nav::on_estop() noexcept {
  ++estop_events_;
  wake();
}

void Nav::shutdown() noexcept {
  shutting_down_ = true;
  wake();
}

}  // namespace rcand::plugins::nav
