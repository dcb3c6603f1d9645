#include "arduino_driver.hpp"

#include <algorithm>
#include <cmath>

namespace rcand::plugins::arduino {

namespace {

using nlohmann::json;
using Clock = std::chrono::steady_clock;

constexpr auto kArduinoPingWait = std::chrono::milliseconds(250);  // per ping while the board boots

std::int64_t arduino_wall_ms() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::system_clock::now().time_since_epoch()).count();
}

std::string arduino_no_answer(const ArduinoSettings& s) {
  return "no answer from the Arduino on " + s.port + " at " + std::to_string(s.baud) + " baud: is the bridge firmware flashed?";
}

// Worker thread: the periodic work. A heartbeat while the drive is non-zero, the ultrasonic when its poll is due.
void arduino_tick(ArduinoBus& bus, ArduinoState& state, const ArduinoSettings& settings, sdk::Logger* log) {
  const auto now = Clock::now();
  std::string line;
  {
    std::lock_guard lock(state.mutex);
    if (!state.started) return;
    if ((state.left_pwm != 0 || state.right_pwm != 0) && now - state.last_drive_sent >= settings.heartbeat * 3 / 4)
      line = drive_line(state.left_pwm, state.right_pwm);
  }
  if (!line.empty()) {
    const auto reply = bus.transact(line, ArduinoBus::Expect::Ack, now + settings.reply_timeout);
    std::lock_guard lock(state.mutex);
    state.last_drive_sent = now;
    ++state.heartbeats;
    if (!reply || reply->kind != Reply::Kind::Ack) {
      state.last_error = "heartbeat: " + (reply ? "the board answered " + reply->error : std::string("no reply"));
      if (log) log->warn("arduino_serial_json: ", state.last_error);
    }
  }
  if (!settings.ultrasonic) return;
  const auto period = std::chrono::duration<double>(1.0 / settings.ultrasonic->poll_hz);
  {
    std::lock_guard lock(state.mutex);
    if (Clock::now() - state.last_poll < period * 0.75) return;
    state.last_poll = Clock::now();
  }
  const auto reply = bus.transact(sensor_line(settings.ultrasonic->sensor_id), ArduinoBus::Expect::Sensor,
                                  Clock::now() + settings.reply_timeout);
  std::lock_guard lock(state.mutex);
  ++state.polls;
  if (reply && reply->kind == Reply::Kind::Sensor && reply->distance_mm) {
    state.distance_mm = reply->distance_mm;
    state.read_at = Clock::now();
    state.read_wall_ms = arduino_wall_ms();
  } else {
    ++state.poll_failures;
    state.last_error = "ultrasonic: " +
                       (reply ? (reply->error.empty() ? "a reply without distance_mm" : reply->error) : std::string("no reply"));
  }
}

}  // namespace

UltrasonicZones::UltrasonicZones(std::shared_ptr<ArduinoState> state, UltrasonicSettings settings)
    : state_(std::move(state)), settings_(std::move(settings)) {}

sdk::ObstacleReading UltrasonicZones::obstacles() const noexcept {
  sdk::ObstacleReading r;
  std::lock_guard lock(state_->mutex);
  if (!state_->distance_mm) return r;  // never read: unavailable
  r.timestamp_ms = state_->read_wall_ms;
  if (Clock::now() - state_->read_at > settings_.stale_after) return r;  // stale: unavailable
  double cm = static_cast<double>(*state_->distance_mm) / 10.0;
  if (*state_->distance_mm < 0) {  // no echo: nothing in range, or a sensor that does not answer
    if (!settings_.no_echo_is_clear) return r;
    cm = settings_.max_range_cm;
  }
  r.available = true;
  r.left_cm = r.center_cm = r.right_cm = r.nearest_cm = cm;
  return r;
}

ArduinoDriver::ArduinoDriver(ArduinoSettings settings, std::shared_ptr<ArduinoBus> bus, sdk::Logger* log, sdk::PluginContext* ctx)
    : settings_(std::move(settings)), log_(log), ctx_(ctx), bus_(std::move(bus)), worker_(std::make_unique<ArduinoWorker>(bus_)) {
  if (settings_.ultrasonic) zones_ = std::make_unique<UltrasonicZones>(state_, *settings_.ultrasonic);
}

ArduinoDriver::~ArduinoDriver() { worker_.reset(); }

void ArduinoDriver::run(ArduinoWorker::Job job, std::chrono::milliseconds deadline, const char* what) {
  const auto result = worker_->run(std::move(job), deadline);
  switch (result.outcome) {
    case ArduinoWorker::Outcome::Done: return;
    case ArduinoWorker::Outcome::Dropped: return;  // a halt superseded it: the motors are to be stopped anyway
    case ArduinoWorker::Outcome::Failed: std::rethrow_exception(result.error);
    case ArduinoWorker::Outcome::TimedOut:
      throw SerialFault(std::string(what) + ": not done within " + std::to_string(deadline.count()) + " ms on " + settings_.port +
                            ": the port is hung or the board is busy",
                        settings_.port);
  }
}

void ArduinoDriver::start() {
  const ArduinoSettings settings = settings_;
  run(
      [settings, state = state_](ArduinoBus& bus) {
        const auto until = Clock::now() + settings.boot_timeout;
        bool answered = false;
        while (!answered && Clock::now() < until) {
          const auto reply = bus.transact(ping_line(), ArduinoBus::Expect::Ack, std::min(until, Clock::now() + kArduinoPingWait));
          answered = reply && reply->kind == Reply::Kind::Ack;  // an error is the bootloader's noise echoed: ping again
        }
        if (!answered)
          throw sdk::DeviceFault(arduino_no_answer(settings), settings.port, "",
                                 "flash firmware/arduino_l298n_bridge.ino (ArduinoJson 7) and check that baud matches "
                                 "the sketch's Serial.begin; ls /dev/serial/by-id/ lists the boards");
        bus.discard_input();  // acks of pings sent while it booted
        bus.transact(stop_line(), ArduinoBus::Expect::Ack, Clock::now() + settings.reply_timeout);
        if (!settings.ultrasonic) return;
        const auto reading = bus.transact(sensor_line(settings.ultrasonic->sensor_id), ArduinoBus::Expect::Sensor,
                                          Clock::now() + settings.reply_timeout);
        if (reading && reading->kind == Reply::Kind::Error)
          throw sdk::DeviceFault("the Arduino on " + settings.port + " does not know sensor '" + settings.ultrasonic->sensor_id +
                                     "': " + reading->error,
                                 settings.port, "", "the bridge firmware reads an HC-SR04 as sensor_type hcsr04");
        if (reading && reading->kind == Reply::Kind::Sensor && reading->distance_mm) {  // the zones are known from the start
          std::lock_guard lock(state->mutex);
          state->distance_mm = reading->distance_mm;
          state->read_at = state->last_poll = Clock::now();
          state->read_wall_ms = arduino_wall_ms();
        }
      },
      settings_.boot_timeout + std::chrono::seconds(1), "start");
  {
    std::lock_guard lock(state_->mutex);
    state_->started = true;
  }
  auto tick = settings_.heartbeat / 2;
  if (settings_.ultrasonic)
    tick = std::min(tick, std::chrono::milliseconds(static_cast<long long>(500.0 / settings_.ultrasonic->poll_hz)));
  worker_->set_idle_task([state = state_, settings, log = log_](ArduinoBus& bus) { arduino_tick(bus, *state, settings, log); },
                         std::max(tick, std::chrono::milliseconds(5)));
  if (zones_ && ctx_ && !sdk::offer<sdk::ObstacleSource>(*ctx_, *zones_) && log_)
    log_->warn(
        "arduino_serial_json: another plugin already offers the obstacle zones; the ultrasonic is not used for the "
        "obstacle stop");
  if (log_) log_->info("arduino_serial_json on ", settings_.port, " at ", settings_.baud, " baud: ", fail_safe());
}

void ArduinoDriver::set_wheel_speeds(double left, double right) {
  const int left_pwm = settings_.pwm_of(left, settings_.invert_left);
  const int right_pwm = settings_.pwm_of(right, settings_.invert_right);
  std::uint64_t generation = 0;
  {
    std::lock_guard lock(state_->mutex);
    if (!state_->started) throw std::logic_error("arduino_serial_json: not started");
    state_->left_pwm = left_pwm;
    state_->right_pwm = right_pwm;
    generation = state_->generation;
    ++state_->commands;
  }
  const std::string line = left_pwm == 0 && right_pwm == 0 ? stop_line() : drive_line(left_pwm, right_pwm);
  auto error = std::make_shared<std::string>();
  run(
      [line, generation, error, state = state_, timeout = settings_.reply_timeout](ArduinoBus& bus) {
        {
          std::lock_guard lock(state->mutex);
          if (state->generation != generation) return;  // a halt came first: stale
        }
        const auto sent = Clock::now();
        const auto reply = bus.transact(line, ArduinoBus::Expect::Ack, sent + timeout);
        std::lock_guard lock(state->mutex);
        state->last_drive_sent = sent;
        if (!reply) *error = "no reply";
        else if (reply->kind == Reply::Kind::Error) *error = "the board answered: " + reply->error;
        if (!error->empty()) state->last_error = "drive: " + *error;
      },
      settings_.command_timeout + settings_.reply_timeout, "drive");
  if (!error->empty())
    throw SerialFault("drive on " + settings_.port + ": " + *error +
                          " (the firmware stops the motors 1 s after the last line "
                          "it understood)",
                      settings_.port);
}

void ArduinoDriver::halt() noexcept {
  try {
    {
      std::lock_guard lock(state_->mutex);
      ++state_->generation;
      ++state_->halts;
      state_->left_pwm = state_->right_pwm = 0;
      if (!state_->started) return;
    }
    const auto deadline = settings_.halt_deadline;
    const auto result =
        worker_->urgent([deadline](ArduinoBus& bus) { bus.send(stop_line(), Clock::now() + deadline); }, deadline);
    if (result.outcome == ArduinoWorker::Outcome::Done || result.outcome == ArduinoWorker::Outcome::Dropped) return;
    std::string why = result.outcome == ArduinoWorker::Outcome::TimedOut
                          ? "not written within " + std::to_string(deadline.count()) + " ms (port hung?)"
                          : "failed";
    if (result.error) try {
        std::rethrow_exception(result.error);
      } catch (const std::exception& e) {
        why += std::string(": ") + e.what();
      }
    why += "; the firmware's watchdog stops the motors 1 s after the last line reached it";
    {
      std::lock_guard lock(state_->mutex);
      ++state_->halts_unconfirmed;
      state_->last_error = "halt " + why;
    }
    if (log_) log_->error("arduino_serial_json halt ", why);
  } catch (...) {  // allocation only
  }
}

void ArduinoDriver::shutdown() noexcept { halt(); }

std::string ArduinoDriver::fail_safe() const {
  return "fail-safe: the bridge firmware stops the motors when no line came for 1 s (rcand resends the drive every " +
         std::to_string(settings_.heartbeat.count()) + " ms while moving, nothing while stopped); halt = {\"cmd\":\"stop\"}";
}

nlohmann::json ArduinoDriver::status() const {
  std::lock_guard lock(state_->mutex);
  json out{{"port", settings_.port},
           {"baud", settings_.baud},
           {"started", state_->started},
           {"left_pwm", state_->left_pwm},
           {"right_pwm", state_->right_pwm},
           {"commands", state_->commands},
           {"heartbeats", state_->heartbeats},
           {"halts", state_->halts},
           {"halts_unconfirmed", state_->halts_unconfirmed},
           {"last_error", state_->last_error.empty() ? json(nullptr) : json(state_->last_error)},
           {"fail_safe", fail_safe()}};
  if (settings_.ultrasonic) {
    json u{{"sensor", settings_.ultrasonic->sensor_id}, {"polls", state_->polls}, {"poll_failures", state_->poll_failures}};
    u["distance_mm"] = state_->distance_mm ? json(*state_->distance_mm) : json(nullptr);
    u["age_ms"] = state_->distance_mm
                      ? json(std::chrono::duration_cast<std::chrono::milliseconds>(Clock::now() - state_->read_at).count())
                      : json(nullptr);
    out["ultrasonic"] = std::move(u);
  }
  return out;
}

}  // namespace rcand::plugins::arduino
