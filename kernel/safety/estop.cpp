#include "kernel/safety/estop.hpp"

#include "libs/base/bounded_text.hpp"
#include "libs/base/logging.hpp"

namespace rcand::kernel {

namespace {
// A reason rcand composes (the restart's "latched when rcand last stopped: <reason> (by <source>)") quotes a
// caller's bounded reason inside its own words: room for both.
constexpr std::size_t kShownReasonBytes = 600;
}  // namespace

Estop::Estop(const sdk::Clock& clock, ActuatorTable& actuators) : clock_(clock), actuators_(actuators) {}

bool Estop::sleep_unless_latched(std::chrono::microseconds duration) const {
  std::unique_lock lock(sleep_mutex_);
  return !sleepers_.wait_for(lock, duration, [this] { return latched_.load(); });
}

void Estop::request_estop(const std::string& reason) noexcept { latch(reason, "plugin", {{}, "plugin", "a plugin", reason}); }

Estop::StopReport Estop::latch(const std::string& reason, const std::string& source, const Origin& origin) noexcept {
  return Announcement{*this, latch_unannounced(reason, source, origin)}.report;  // copied, then announced
}

Estop::StopReport Estop::latch_unannounced(const std::string& reason, const std::string& source, const Origin& origin) noexcept {
  StopReport report;
  const auto start = clock_.now_us();
  const auto deadline = std::chrono::steady_clock::now() + kHaltDeadline;
  epoch_.fetch_add(1);
  report.newly_latched = !latched_.exchange(true);
  try {
    // Recorded before the halt (bounded copies, a few microseconds), so whoever sees a motor stop also sees why in
    // GET /api/estop, /api/status, telemetry and the latch record (a reason may be any caller's or plugin's text).
    if (report.newly_latched) {  // a repeated stop keeps the first reason: nothing to copy
      report.shown_reason = bounded_text(reason, kShownReasonBytes);
      report.shown_source = bounded_text(source);
      std::lock_guard lock(info_mutex_);
      info_ = {
          true,
          clock_.wall_ms(),
          report.shown_reason,
          report.shown_source,
          {bounded_text(origin.principal), origin.kind, bounded_text(origin.from), bounded_text(origin.note, kShownReasonBytes)}};
    }
  } catch (...) {  // no memory for the texts: the halt goes on regardless
  }
  report.drivers = halt_everything(deadline);
  // Commands that passed the gate's latch check before the flag was set: wait (bounded) until they left the gate,
  // which they do only after the gate halted their actuator again (see the ordering guarantee in estop.hpp).
  report.commands_in_flight = actuators_.wait_for_commands(deadline, latched_);
  report.latency_us = clock_.now_us() - start;
  try {
    for (const auto& id : report.commands_in_flight) {
      const std::string why = "a command that entered the motion gate before the latch was still running at the " +
                              std::to_string(kHaltDeadline.count()) + " ms deadline; the gate halts " + id + " when it returns";
      logger("kernel.estop")->error("actuator {}: {}", id, why);
      for (auto& driver : report.drivers) {
        if (driver.id != id) continue;
        driver.halted = false;
        driver.error = driver.state == "halted" ? why : driver.error + "; " + why;
        if (driver.state == "halted") driver.state = "command_in_flight";
      }
    }
    {
      std::lock_guard lock(sleep_mutex_);  // pairs with the predicate check in sleep_unless_latched
    }
    sleepers_.notify_all();
  } catch (...) {  // bookkeeping must never undo a stop that already happened
  }
  return report;
}

void Estop::announce(const StopReport& report) noexcept {
  try {
    for (auto& listener : listeners_) listener();
    if (report.newly_latched)
      logger("kernel.estop")
          ->warn("e-stop latched by {}: {} ({} actuators halted in {} us)", report.shown_source, report.shown_reason,
                 report.drivers.size(), report.latency_us);
  } catch (...) {  // bookkeeping must never undo a stop that already happened
  }
}

std::vector<HaltReport> Estop::halt_everything(std::chrono::steady_clock::time_point deadline) noexcept {
  DeadlineCrew* crew = halt_crew_.load();
  if (crew == nullptr) return actuators_.halt_all(clock_);
  const auto outcomes = crew->run_all(deadline);
  std::vector<HaltReport> reports;
  try {
    reports.reserve(outcomes.size());
    for (const auto& outcome : outcomes) {
      auto& report = reports.emplace_back();
      report.id = outcome.name;
      report.halted = outcome.state == DeadlineCrew::State::Done;
      report.latency_us = outcome.latency_us;
      if (outcome.state == DeadlineCrew::State::Pending) {
        report.state = "halt_pending";
        report.error = "halt() did not return within " + std::to_string(kHaltDeadline.count()) + " ms";
      } else if (outcome.state == DeadlineCrew::State::Failed) {
        report.state = "halt_failed";
        report.error = "halt() threw: " + outcome.error;
        // A driver that cannot halt must not be commanded again, even after the e-stop is cleared.
        if (auto* slot = actuators_.find(outcome.name); slot != nullptr && slot->health != nullptr)
          slot->health->mark_failed(report.error);
      }
      if (!report.halted) logger("kernel.estop")->error("actuator {}: {}", report.id, report.error);
    }
  } catch (...) {  // reporting failed (out of memory); the halts themselves were started
  }
  return reports;
}

bool Estop::clear() {
  const bool was = latched_.exchange(false);
  std::lock_guard lock(info_mutex_);
  info_ = {};
  if (was) logger("kernel.estop")->info("e-stop cleared");
  for (auto& listener : clear_listeners_) listener();
  return was;
}

void Estop::restate(std::string reason, std::string source) {
  std::lock_guard lock(info_mutex_);
  if (!latched_.load()) return;
  info_.reason = bounded_text(reason, kShownReasonBytes);
  info_.source = bounded_text(source);
  info_.origin = {{}, "startup", {}, {}};
}

void Estop::on_cleared(std::function<void()> listener) { clear_listeners_.push_back(std::move(listener)); }

Estop::Snapshot Estop::snapshot() const {
  std::lock_guard lock(info_mutex_);
  Snapshot copy = info_;
  copy.estopped = latched_.load();
  return copy;
}

void Estop::on_latched(std::function<void()> listener) { listeners_.push_back(std::move(listener)); }

}  // namespace rcand::kernel
