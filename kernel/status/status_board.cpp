#include "kernel/status/status_board.hpp"

#include <algorithm>
#include <atomic>
#include <future>
#include <iterator>
#include <limits>
#include <mutex>

#include "kernel/api/capability_routes.hpp"
#include "libs/base/bounded_text.hpp"
#include "libs/base/logging.hpp"
#include "libs/base/plugin_health.hpp"
#include "libs/base/worker_thread.hpp"
#include "rcand/sdk/interfaces/pose_source.hpp"

namespace rcand::kernel {
namespace {

using nlohmann::json;
using Clock = std::chrono::steady_clock;

// The top-level "pose" and whether the robot drives itself ("nav_running"), from the robot's PoseSource service
// (nav's dead-reckoned pose), read once per rebuild: none offered (no nav, or nav failed), no pose and not running.
bool add_pose(const ServiceDirectory& directory, json& doc) {
  const auto* source = sdk::find<sdk::PoseSource>(directory);
  if (source == nullptr) return false;
  const sdk::PoseReading reading = source->read();
  if (reading.available)
    doc["pose"] = {{"x_m", reading.pose.x_m}, {"y_m", reading.pose.y_m}, {"heading_deg", reading.pose.heading_deg}};
  return reading.busy;
}

std::string dump(const json& doc) {
  // Invalid UTF-8 from a plugin is replaced, never a reason to fail the document.
  return doc.dump(-1, ' ', false, json::error_handler_t::replace);
}

std::int64_t steady_us() {
  return std::chrono::duration_cast<std::chrono::microseconds>(Clock::now().time_since_epoch()).count();
}

}  // namespace

namespace board {

struct DriverView {
  std::string id, protocol, interface;
  bool failed = false;
  Fault fault;
};

struct Verdict {
  std::string state = "ok";  // ok | degraded | error
  Fault fault;               // why, when not ok: the reason names the drivers; device, OS error and hint of the first
};

// A capability's state from the drivers it needs: for an interface every provider of which failed, "error"; for one
// some providers of which failed, "degraded". The first error wins, else the first degradation.
Verdict follow_drivers(const std::vector<std::string>& needs, const std::vector<DriverView>& drivers) {
  Verdict verdict;
  for (const auto& interface : needs) {
    std::vector<const DriverView*> providers, failed;
    for (const auto& driver : drivers) {
      if (driver.interface != interface) continue;
      providers.push_back(&driver);
      if (driver.failed) failed.push_back(&driver);
    }
    const bool error = !failed.empty() && failed.size() == providers.size();
    if (failed.empty() || (!error && verdict.state != "ok")) continue;
    std::string names;
    for (const auto* driver : failed)
      names += (names.empty() ? "" : "; ") + driver->id + " (" + driver->protocol + "): " + driver->fault.reason;
    verdict.state = error ? "error" : "degraded";
    verdict.fault = failed.front()->fault;
    verdict.fault.reason = error ? (providers.size() == 1 ? "needs a " + interface + " actuator, and it failed: "
                                                          : "needs a " + interface + " actuator, and every one failed: ") +
                                       names
                                 : std::to_string(failed.size()) + " of its " + std::to_string(providers.size()) + " " +
                                       interface + " actuators failed: " + names;
    if (error) break;
  }
  return verdict;
}

}  // namespace board

void StatusBoard::add_fault(json& item, const Fault& fault) {
  item["reason"] = fault.reason;
  if (!fault.device.empty()) item["device"] = fault.device;
  if (!fault.os_error.empty()) item["os_error"] = fault.os_error;
  if (!fault.hint.empty()) item["hint"] = fault.hint;
}

class StatusBoard::Impl final : public StatusSink, public std::enable_shared_from_this<StatusBoard::Impl> {
 public:
  struct Snapshot {
    std::string body[2];  // [latched]: the e-stop fields differ
    json doc;             // not latched
    bool nav_running = false;
    std::uint64_t changes = 0;  // changes_ when the round that built it began
    std::size_t failed = 0;     // instances marked failed when it was built
    std::size_t faults = 0;     // instances whose status reported a fault (sdk/capability.hpp, "fault")
    std::size_t starting = 0;   // capabilities still starting when it was built
  };

  Impl(std::vector<Source> sources, KernelServices& services, json fixed, std::int64_t started_us)
      : services_(services), fixed_(std::move(fixed)), started_us_(started_us), created_us_(services.clock.now_us()) {
    for (auto& source : sources) {
      auto entry = std::make_unique<Entry>();
      entry->source = std::move(source);
      entry->tokens_us = created_us_;
      entries_.push_back(std::move(entry));
    }
    current_.store(build(0));
  }

  // After construction (the listener holds a weak reference). Startup only, as Estop requires. A latch needs no
  // round: both variants are built, so body() is right at once, and what the capabilities' on_estop() change they
  // publish. A clear does: nav's job may have ended meanwhile, and robot_state() reads it from the snapshot.
  void listen_to_estop() {
    services_.estop.on_cleared([weak = weak_from_this()] {
      if (auto self = weak.lock()) self->request_round();
    });
  }

  void start() {
    if (started_.exchange(true)) return;
    running_.store(true);
    services_.status_sink.attach(this);
    refresh();
    schedule_tick();
  }

  void stop() noexcept {
    if (!running_.exchange(false)) return;
    services_.status_sink.detach();
    worker_.join();  // a round in progress finishes; queued ones return at once (running_ is false)
    answer_waiters(std::numeric_limits<std::uint64_t>::max());
  }

  std::shared_ptr<const std::string> body() const noexcept { return body_of(current_.load()); }

  void when_current(std::function<void(std::shared_ptr<const std::string>)> answer) {
    auto snapshot = current_.load();
    // marked failed or up since: nobody announces that, so it counts as a change
    if (snapshot->failed != failed_now() || snapshot->starting != starting_now()) {
      changes_.fetch_add(1);
      request_round();
    }
    const std::uint64_t need = changes_.load();
    if (snapshot->changes < need) {
      // Under the lock: a round that finished meanwhile answered its waiters under it, and stop() answers all
      // waiters under it once running_ is false.
      std::lock_guard lock(waiters_mutex_);
      snapshot = current_.load();
      if (snapshot->changes < need && running_.load()) {
        waiters_.push_back({need, std::move(answer)});
        return;
      }
    }
    answer(body_of(snapshot));
  }

  json document() const {
    const auto snapshot = current_.load();
    json doc = snapshot->doc;
    if (services_.estop.latched()) {
      doc["estopped"] = true;
      doc["state"] = "estop";
    }
    return doc;
  }

  std::string robot_state() const {
    if (services_.estop.latched()) return "estop";
    const auto snapshot = current_.load();
    if (failed_now() > 0 || snapshot->faults > 0) return "error";
    return snapshot->nav_running ? "running" : "idle";
  }

  void notify() noexcept { request_round(); }

  void refresh() {
    if (!running_.load()) return;
    auto done = std::make_shared<std::promise<void>>();
    auto finished = done->get_future();
    worker_.post([this, done] {
      round(true);
      done->set_value();
    });
    finished.wait();
  }

  void publish(const InstanceContext& from, const json& status) noexcept override {
    Entry* entry = nullptr;
    for (const auto& candidate : entries_)
      if (candidate->source.health == &from.health()) entry = candidate.get();
    if (entry == nullptr) return;
    bool shown = true;
    try {
      json copy = status;  // the one allocation-heavy step, outside the lock
      // Of a driver only the fault is shown (its state): a publish that keeps it, soon after the last one, changes
      // nothing a reader sees and waits for the tick's round (a moving drive publishes at 10 Hz).
      const auto fault = entry->source.driver ? reported_fault(status) : std::nullopt;
      const std::int64_t now = services_.clock.now_us();
      bool counted = false;
      {
        std::lock_guard lock(entry->mutex);
        shown = !entry->source.driver || fault != entry->published_fault || now - entry->pending_us >= kPollAfter.count() * 1000;
        entry->tokens = std::min(kWaitBurst, entry->tokens + static_cast<double>(now - entry->tokens_us) * kWaitPerSecond / 1e6);
        entry->tokens_us = now;
        if (shown && entry->tokens >= 1.0) {
          entry->tokens -= 1.0;
          counted = true;
        }
        entry->published_fault = fault;
        entry->pending = std::move(copy);
        entry->pending_us = now;
      }
      if (counted) changes_.fetch_add(1);  // after the store: a round that sees the count takes the value
    } catch (...) {                        // no memory for the copy: the previous value stays, and the poll fallback catches up
    }
    if (shown) request_round();
  }

 private:
  struct Entry {
    Source source;
    // Written by publishing plugin threads, taken by the status thread.
    std::mutex mutex;
    std::optional<json> pending;
    std::int64_t pending_us = 0;                 // the latest publish, taken or not
    std::optional<std::string> published_fault;  // a driver's, as of that publish
    double tokens = kWaitBurst;  // when_current() waits for this instance's publishes while there are tokens
    std::int64_t tokens_us = 0;
    // The status thread's own.
    std::optional<json> last;
    std::int64_t last_us = 0;  // when `last` was published or answered
    std::optional<std::int64_t> asked_us;
    mutable std::optional<json> up_item;  // item_when_up()'s fields, taken once it is up (status thread)
  };
  struct Waiter {
    std::uint64_t need;
    std::function<void(std::shared_ptr<const std::string>)> answer;
  };

  std::shared_ptr<const std::string> body_of(std::shared_ptr<const Snapshot> snapshot) const noexcept {
    const std::string* body = &snapshot->body[services_.estop.latched() ? 1 : 0];
    return std::shared_ptr<const std::string>(std::move(snapshot), body);
  }

  std::size_t starting_now() const noexcept {
    return static_cast<std::size_t>(std::count_if(entries_.begin(), entries_.end(), [](const auto& entry) {
      return entry->source.starting != nullptr && entry->source.starting->load();
    }));
  }

  std::size_t failed_now() const noexcept {
    std::size_t failed = 0;
    for (const auto& entry : entries_)
      if (entry->source.health != nullptr && entry->source.health->failed()) ++failed;
    return failed;
  }

  // Coalesced: at most one round queued, and none sooner than kRebuildGap after the previous one began.
  void request_round() noexcept {
    if (!running_.load() || round_requested_.exchange(true)) return;
    try {
      const std::int64_t wait_us = last_round_us_.load() + kRebuildGap.count() * 1000 - steady_us();
      auto task = [this] { round(false); };
      if (wait_us <= 0) worker_.post(std::move(task));
      else worker_.schedule(std::chrono::microseconds(wait_us), std::move(task));
    } catch (...) {  // no memory for the task: the next tick rebuilds
      round_requested_.store(false);
    }
  }

  void schedule_tick() {
    worker_.schedule(kTick, [this] {
      round(true);
      if (running_.load()) schedule_tick();
    });
  }

  // The status thread: takes what was published, asks the silent (`ask`), rebuilds, answers the waiters it can.
  void round(bool ask) noexcept {
    if (!running_.load()) return;
    last_round_us_.store(steady_us());
    round_requested_.store(false);  // a change from here on requests another round
    const std::uint64_t seen = changes_.load();
    try {
      for (auto& entry : entries_) {  // what was published since
        std::lock_guard lock(entry->mutex);
        if (!entry->pending) continue;
        entry->last = std::move(entry->pending);
        entry->last_us = entry->pending_us;
        entry->pending.reset();
      }
      if (ask) ask_silent();
      current_.store(build(seen));
    } catch (const std::exception& e) {
      logger("kernel.status")->error("status rebuild failed: {}", e.what());
    }
    answer_waiters(seen);
  }

  // One at a time: each takes microseconds, and one that hangs costs one status deadline once (it is then failed
  // and never asked again).
  void ask_silent() {
    for (auto& entry : entries_) {
      const auto& source = entry->source;
      if (!source.poll || (source.health != nullptr && source.health->failed())) continue;
      if (source.starting != nullptr && source.starting->load()) continue;
      const std::int64_t now = services_.clock.now_us();
      const std::int64_t poll_after = std::chrono::microseconds(kPollAfter).count();
      if (entry->last && now - entry->last_us < poll_after) continue;
      if (entry->asked_us && now - *entry->asked_us < poll_after) continue;
      entry->asked_us = now;
      if (auto value = source.poll()) {
        entry->last = std::move(*value);
        entry->last_us = services_.clock.now_us();
      }
    }
  }

  // One instance's item: "failed" with its fault; a capability's state following the drivers it needs; "stale".
  json item_of(const Entry& entry, const std::vector<board::DriverView>& drivers, std::int64_t now) const {
    const auto& source = entry.source;
    if (source.starting != nullptr && source.starting->load()) {
      json item = source.item;
      item["state"] = "starting";
      return item;
    }
    if (source.item_when_up && !entry.up_item) entry.up_item = source.item_when_up();  // once: the routes it serves
    json item = source.item;
    if (entry.up_item) item.update(*entry.up_item);
    if (source.health != nullptr && source.health->handler_errors() > 0)
      item["handler_errors"] = source.health->handler_errors();  // requests answered 500: the handler threw
    if (source.health != nullptr && source.health->failed()) {
      item["state"] = "failed";
      add_fault(item, source.health->fault());
      return item;
    }
    if (auto fault = entry.last ? reported_fault(*entry.last) : std::nullopt) {
      item["state"] = "error";  // it runs, but cannot do its job: a camera with no picture
      item["reason"] = std::move(*fault);
    } else {
      const board::Verdict verdict = board::follow_drivers(source.needs, drivers);
      item["state"] = verdict.state;
      if (verdict.state != "ok") add_fault(item, verdict.fault);
    }
    const std::int64_t age = now - (entry.last ? entry.last_us : created_us_);
    if (age > std::chrono::microseconds(kStaleAfter).count()) {
      item["stale"] = true;
      item["age_ms"] = age / 1000;
    }
    if (entry.last && !source.driver) item["status"] = *entry.last;
    return item;
  }

  std::shared_ptr<const Snapshot> build(std::uint64_t changes) const {
    auto snapshot = std::make_shared<Snapshot>();
    snapshot->changes = changes;
    snapshot->starting = starting_now();  // before reading them: a capability up meanwhile makes the next one
    const std::int64_t now = services_.clock.now_us();
    json doc = fixed_;
    json capabilities = json::object();
    json drivers = json::array();
    const bool nav_running = add_pose(services_.directory, doc);
    std::vector<board::DriverView> views;  // what the capabilities' states follow
    for (const auto& entry : entries_) {
      const auto& source = entry->source;
      if (!source.driver) continue;
      const bool failed = source.health != nullptr && source.health->failed();
      std::optional<std::string> reported = !failed && entry->last ? reported_fault(*entry->last) : std::nullopt;
      views.push_back({source.name, source.item.value("protocol", ""), source.item.value("interface", ""),
                       failed || reported.has_value(),
                       failed ? source.health->fault() : Fault{reported.value_or(""), {}, {}, {}}});
    }
    for (const auto& entry : entries_) {
      json item = item_of(*entry, views, now);
      if (item["state"] == "failed") ++snapshot->failed;
      if (item["state"] == "error") ++snapshot->faults;
      if (entry->source.driver) drivers.push_back(std::move(item));
      else capabilities[entry->source.name] = std::move(item);
    }
    const char* state = snapshot->failed + snapshot->faults > 0 ? "error" : nav_running ? "running" : "idle";
    snapshot->nav_running = nav_running;
    doc["state"] = state;
    doc["estopped"] = false;
    doc["uptime_s"] = (now - started_us_) / 1'000'000;
    doc["drivers"] = std::move(drivers);
    doc["capabilities"] = std::move(capabilities);
    doc["nav_running"] = nav_running;
    if (doc.contains("plugins")) add_plugin_health(doc["plugins"], doc, false);  // a loaded library may not be ok
    snapshot->body[0] = dump(doc);
    doc["state"] = "estop";
    doc["estopped"] = true;
    snapshot->body[1] = dump(doc);
    doc["state"] = state;
    doc["estopped"] = false;
    snapshot->doc = std::move(doc);
    return snapshot;
  }

  void answer_waiters(std::uint64_t seen) noexcept {
    std::vector<Waiter> ready;
    {
      std::lock_guard lock(waiters_mutex_);
      if (waiters_.empty()) return;
      auto keep = std::partition(waiters_.begin(), waiters_.end(), [seen](const Waiter& w) { return w.need > seen; });
      std::move(keep, waiters_.end(), std::back_inserter(ready));
      waiters_.erase(keep, waiters_.end());
    }
    for (auto& waiter : ready) {
      try {
        waiter.answer(body());
      } catch (...) {  // the caller's answer must not throw; it cannot stop the status thread either
      }
    }
  }

  KernelServices& services_;
  const json fixed_;
  const std::int64_t started_us_;
  const std::int64_t created_us_;                // the age of an entry nothing refreshed yet
  std::vector<std::unique_ptr<Entry>> entries_;  // fixed after construction: publishers search it without a lock

  std::atomic<std::shared_ptr<const Snapshot>> current_;
  std::atomic<std::uint64_t> changes_{0};  // publishes within their rate, failures found by when_current()
  std::atomic<bool> started_{false}, running_{false};
  std::atomic<bool> round_requested_{false};
  std::atomic<std::int64_t> last_round_us_{0};  // steady clock
  std::mutex waiters_mutex_;
  std::vector<Waiter> waiters_;
  WorkerThread worker_{"kernel.status",
                       [](const std::string& why) { logger("kernel.status")->error("status thread task failed: {}", why); },
                       WorkerThread::Priority::Background};
};

// ---- StatusBoard ------------------------------------------------------------------------------------------------

std::optional<std::string> StatusBoard::reported_fault(const json& status) {
  if (!status.is_object()) return std::nullopt;
  const auto fault = status.find("fault");
  if (fault == status.end() || !fault->is_string() || fault->get_ref<const std::string&>().empty()) return std::nullopt;
  return bounded_text(fault->get_ref<const std::string&>(), kFaultTextBytes);
}

json StatusBoard::fixed_fields(const RobotIdentity& identity, const std::vector<std::string>& caps, const PluginHost& host,
                               std::string_view version) {
  json plugins = json::array();
  for (const auto& record : host.records()) {
    json item{{"id", record->id}, {"version", record->version}, {"state", std::string(to_string(record->state))}};
    if (!record->reason.empty()) item["reason"] = record->reason;
    plugins.push_back(std::move(item));
  }
  return {{"ruri", identity.ruri},        {"name", identity.name}, {"version", std::string(version)},
          {"rcan_version", kRcanVersion}, {"caps", caps},          {"plugins", std::move(plugins)}};
}

std::vector<StatusBoard::Source> StatusBoard::sources_of(PluginRuntime& runtime) {
  // Polled through the runtime even without an object now: a reload may start one (status_of answers nullopt until).
  const auto poll = [&runtime](const auto& instance) { return [&runtime, &instance] { return runtime.status_of(instance); }; };
  std::vector<Source> sources;
  for (const auto& instance : runtime.capabilities())  // the routes it serves, once it is up
    sources.push_back({instance.name,
                       false,
                       {{"plugin", instance.plugin_id}, {"routes", json::array()}},
                       &instance.health,
                       poll(instance),
                       instance.needs,
                       &instance.starting,
                       [&instance] {
                         return json{{"routes", served_routes(instance)}};
                       }});
  for (const auto& instance : runtime.drivers()) {
    nlohmann::json item{
        {"id", instance.id}, {"protocol", instance.protocol}, {"plugin", instance.plugin_id}, {"actuates", instance.actuates}};
    if (!instance.interface.empty()) item["interface"] = instance.interface;
    sources.push_back({instance.id, true, std::move(item), &instance.health, poll(instance)});
  }
  return sources;
}

StatusBoard::StatusBoard(PluginRuntime& runtime, KernelServices& services, json fixed, std::int64_t started_us)
    : StatusBoard(sources_of(runtime), services, std::move(fixed), started_us) {}

StatusBoard::StatusBoard(std::vector<Source> sources, KernelServices& services, json fixed, std::int64_t started_us)
    : impl_(std::make_shared<Impl>(std::move(sources), services, std::move(fixed), started_us)) {
  impl_->listen_to_estop();
}

StatusBoard::~StatusBoard() { stop(); }

void StatusBoard::start() { impl_->start(); }
void StatusBoard::stop() noexcept { impl_->stop(); }
std::shared_ptr<const std::string> StatusBoard::body() const noexcept { return impl_->body(); }
void StatusBoard::when_current(std::function<void(std::shared_ptr<const std::string>)> answer) {
  impl_->when_current(std::move(answer));
}
json StatusBoard::document() const { return impl_->document(); }
std::string StatusBoard::robot_state() const { return impl_->robot_state(); }
void StatusBoard::notify() noexcept { impl_->notify(); }
void StatusBoard::refresh() { impl_->refresh(); }

}  // namespace rcand::kernel
