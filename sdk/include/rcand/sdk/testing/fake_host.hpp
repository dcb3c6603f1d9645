// The fake host: unit-test a plugin with doctest and no kernel.
//
//   rcand::sdk::testing::FakeHost host({{"safety", {{"watchdog_ms", 500}}}});
//   host.load(RCAND_ENTRY_FUNCTION);                        // descriptor checked as the kernel does
//   host.add_driver("base", "sim_diff_drive");              // factory, then start()
//   host.add_capability("teleop");                          // factory, start(), routes()
//   auto r = host.call("POST", "/api/action", {{"type", "move"}, {"linear", 0.5}, {"angular", 0.0}});
//   host.advance(std::chrono::milliseconds(500));           // timers due by then run, in order
//   host.last_published_status("teleop");                   // what the instance last gave publish_status()
//
// Same semantics as the kernel, deterministically: one thread (the test's), a manual clock, workers that never
// start threads (tasks and due timers run on run_pending() / advance()), a motion gate that refuses while the
// e-stop is latched and re-halts a command that raced a latch, and HTTP routing with the kernel's scope and
// e-stop checks. Handlers run inline on the test thread.
#pragma once

#include <nlohmann/json.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "rcand/sdk/abi.h"
#include "rcand/sdk/bounded_text.hpp"
#include "rcand/sdk/capability.hpp"
#include "rcand/sdk/context.hpp"
#include "rcand/sdk/contract/door.hpp"
#include "rcand/sdk/contract/plan.hpp"
#include "rcand/sdk/contract/requests.hpp"
#include "rcand/sdk/contract/settings.hpp"
#include "rcand/sdk/driver.hpp"
#include "rcand/sdk/registrar.hpp"
#include "rcand/sdk/services.hpp"
#include "rcand/sdk/testing/fake_scheduler.hpp"
#include "rcand/sdk/testing/manual_clock.hpp"
#include "rcand/sdk/testing/recording_logger.hpp"

namespace rcand::sdk::testing {

// Misuse of the host, or a plugin instance that failed to construct or start (the kernel would record it
// failed; a test wants to know at once).
class HostError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};
// The plugin was refused at load: bad descriptor, incompatible ABI, manifest mismatch, registration failed.
class LoadError : public HostError {
 public:
  using HostError::HostError;
};

class FakeHost {
 public:
  explicit FakeHost(nlohmann::json robot_config = {})
      : robot_config_(robot_config.is_object() ? std::move(robot_config) : nlohmann::json::object()),
        scheduler_(clock_),
        kernel_log_(sink_, "kernel.fake_host"),
        estop_(*this),
        gate_(*this) {
    scheduler_.on_failure([this](const std::string& worker, const std::string& what) {
      task_failures_.push_back(worker + ": " + what);
      kernel_log_.error("task on worker '", worker, "' threw: ", what);
    });
  }

  // Not copyable or movable (plugin contexts point into it). The copy constructor takes a non-const reference
  // on purpose: a braced robot config, FakeHost host({{"safety", {...}}}), then has exactly one viable constructor.
  FakeHost(FakeHost&) = delete;
  FakeHost& operator=(const FakeHost&) = delete;

  // The kernel's shutdown order: capabilities stop, actuators halt, drivers shut down; queued tasks are
  // dropped before any plugin object is destroyed (they may point at it); contexts outlive their instances.
  ~FakeHost() {
    // As the kernel: an instance's service offers are withdrawn before its shutdown().
    for (auto it = capabilities_.rbegin(); it != capabilities_.rend(); ++it) {
      withdraw_offers((*it)->name);
      (*it)->instance->shutdown();
    }
    for (auto it = drivers_.rbegin(); it != drivers_.rend(); ++it) {
      withdraw_offers((*it)->id);
      if ((*it)->actuator) (*it)->actuator->halt();
      (*it)->instance->shutdown();
    }
    scheduler_.clear();
    for (auto& slot : capabilities_) slot->instance.reset();
    for (auto& slot : drivers_) slot->instance.reset();
  }

  // ---- loading ---------------------------------------------------------------------------------------------

  // Checks the descriptor like the kernel (magic, size, ABI major/minor, id, version), then calls the register
  // function once. Throws LoadError with the reason; on failure nothing of the plugin is kept.
  void load(rcand_plugin_entry_fn entry) { load_impl(entry, nullptr); }

  // As load(entry), and also checks the plugin against its manifest as the kernel does: id and version equal,
  // registrations equal to "provides", a well-formed "config" schema; instance settings are then validated against
  // that schema (none: the plugin takes no settings), with defaults filled in, before each factory runs. The config
  // rules are the kernel's own (rcand/sdk/contract/settings.hpp).
  void load(rcand_plugin_entry_fn entry, const nlohmann::json& manifest) { load_impl(entry, &manifest); }

  // ---- instances -------------------------------------------------------------------------------------------

  // One `drivers[]` entry: calls the protocol's factory (settings carry `id` and `protocol`), then start().
  Driver& add_driver(std::string id, std::string protocol, nlohmann::json settings = {}) {
    if (find_driver(id)) throw HostError("driver id '" + id + "' is already in use");
    const auto reg = driver_registrations_.find(protocol);
    if (reg == driver_registrations_.end())
      throw HostError("no loaded plugin registers driver protocol '" + protocol + "'" + known(driver_registrations_));
    if (settings.is_null()) settings = nlohmann::json::object();
    if (!settings.is_object()) throw HostError("drivers[" + id + "]: settings must be an object");
    settings["id"] = id;
    settings["protocol"] = protocol;
    settings = apply_schema(reg->second.plugin_id, "driver", protocol, std::move(settings), "drivers[" + id + "]");

    auto slot = std::make_unique<DriverSlot>();
    slot->id = id;
    slot->context = std::make_unique<Context>(*this, reg->second.plugin_id, id, std::move(settings));
    try {
      slot->instance = reg->second.factory(*slot->context);
    } catch (const std::exception& e) {
      withdraw_offers(id);
      throw HostError("driver '" + id + "': factory threw: " + e.what());
    }
    if (!slot->instance) throw HostError("driver '" + id + "': factory returned null");
    if (reg->second.info.actuates) {
      slot->actuator = dynamic_cast<ActuatorDriver*>(slot->instance.get());
      if (!slot->actuator) throw HostError("driver '" + id + "': registered as actuating but the factory made no ActuatorDriver");
      if (slot->actuator->interface_name() != reg->second.info.interface)
        throw HostError("driver '" + id + "': registered interface '" + reg->second.info.interface +
                        "' but the instance implements '" + std::string(slot->actuator->interface_name()) + "'");
    }
    try {
      slot->instance->start();
    } catch (const std::exception& e) {
      withdraw_offers(id);
      throw HostError("driver '" + id + "': start() threw: " + e.what());
    }
    drivers_.push_back(std::move(slot));
    return *drivers_.back()->instance;
  }

  // Installs a hand-made driver (no plugin), e.g. RecordingDrive, so a capability can be tested alone.
  template <class T, class... Args> T& add_driver_instance(std::string id, Args&&... args) {
    if (find_driver(id)) throw HostError("driver id '" + id + "' is already in use");
    auto slot = std::make_unique<DriverSlot>();
    slot->id = id;
    slot->context = std::make_unique<Context>(*this, "test", id, nlohmann::json{{"id", id}});
    auto instance = std::make_unique<T>(std::forward<Args>(args)...);
    T& ref = *instance;
    slot->instance = std::move(instance);
    slot->actuator = dynamic_cast<ActuatorDriver*>(slot->instance.get());
    slot->instance->start();
    drivers_.push_back(std::move(slot));
    return ref;
  }

  // A capability: factory (settings = `settings`, or when null/empty the robot config's
  // runtime.capabilities.<name>), start(), routes().
  Capability& add_capability(std::string name, nlohmann::json settings = {}) {
    if (find_capability(name)) throw HostError("capability '" + name + "' is already added");
    const auto reg = capability_registrations_.find(name);
    if (reg == capability_registrations_.end())
      throw HostError("no loaded plugin registers capability '" + name + "'" + known(capability_registrations_));
    if (settings.is_null() || (settings.is_object() && settings.empty())) {
      const auto configured = robot_config_.sub("runtime.capabilities." + name).raw();
      settings = configured.is_object() ? configured : nlohmann::json::object();
    }
    if (!settings.is_object()) throw HostError("runtime.capabilities." + name + ": settings must be an object");
    settings = apply_schema(reg->second.plugin_id, "capability", name, std::move(settings), "runtime.capabilities." + name);

    auto slot = std::make_unique<CapabilitySlot>();
    slot->name = name;
    slot->custom = name.find('.') != std::string::npos;  // reverse-domain names are custom (§9)
    slot->context = std::make_unique<Context>(*this, reg->second.plugin_id, name, std::move(settings));
    try {
      slot->instance = reg->second.factory(*slot->context);
      if (!slot->instance) throw HostError("factory returned null");
      slot->instance->start();
      slot->routes = slot->instance->routes();
    } catch (const std::exception& e) {
      withdraw_offers(name);
      throw HostError("capability '" + name + "': " + e.what());
    }
    check_routes(*slot);
    capabilities_.push_back(std::move(slot));
    return *capabilities_.back()->instance;
  }

  // ---- requests --------------------------------------------------------------------------------------------

  // Routes as the kernel, through the same door (rcand/sdk/contract/door.hpp): the row of route_table() the request
  // matches (404/405 for none; POST /api/action: then its type's row), its scope (403), the e-stop for a motion row
  // (423, handler not called), then the handler, or a fallback row's 404 (not declared, no such route) or 405;
  // afterwards run_pending().
  // The request carries `scopes` as what the caller's credential grants (default: every scope of `role`, as a
  // pre-shared token; narrower: a JWT's scope claim) and a TestCredential, as rcand attaches its own.
  Response call(std::string method, std::string path, nlohmann::json body = {}, Role role = Role::Owner,
                std::optional<std::vector<Scope>> scopes = std::nullopt) {
    Response response = dispatch(std::move(method), std::move(path), std::move(body), role, std::move(scopes));
    run_pending();
    return response;
  }

  // The capability route table the running capabilities serve, as rcand builds it (rcand/sdk/contract/door.hpp):
  // every request call() makes goes through it. Routes left out are named in `refused`.
  contract::RouteTable route_table() const {
    std::vector<contract::RunningCapability> running;
    for (const auto& slot : capabilities_) {
      if (slot->failed) continue;
      auto& cap = running.emplace_back(contract::RunningCapability{slot->name, {}});
      for (const auto& r : slot->routes) cap.routes.push_back({r.method, r.path, r.action_type, r.scope, r.motion, false});
    }
    return contract::route_table(running);
  }

  // The credential the fake host attaches to every request (Request::credential): opaque to the plugin, as rcand's.
  // A RequestDispatcher double in a plugin's test can check that the plugin handed the caller's one back.
  struct TestCredential final : Credential {
    std::string principal;
    Role role = Role::Guest;
  };

  // ---- e-stop ----------------------------------------------------------------------------------------------

  // Latches exactly as POST /api/stop: latch, halt every actuator, then on_estop() on every capability.
  void latch_estop(std::string reason) { estop_.request_estop(reason); }
  void clear_estop() noexcept { estop_.latched_ = false; }
  bool estopped() const noexcept { return estop_.latched(); }
  // The e-stop will latch at `at_us` on the manual clock: during advance(), or inside a plugin's
  // sleep_unless_latched() that spans that instant (which then returns false at exactly that time).
  void latch_estop_at(std::int64_t at_us, std::string reason) { scheduled_latches_.emplace(at_us, std::move(reason)); }

  // ---- time and workers ------------------------------------------------------------------------------------

  // Moves the clock forward by `by`, running every task and timer that falls due, each at its due time.
  std::size_t advance(std::chrono::microseconds by) {
    const std::int64_t target = clock_.now_us() + std::max<std::int64_t>(0, by.count());
    std::size_t ran = 0;
    for (;;) {
      const auto task_due = scheduler_.next_due();
      const bool latch_due = !scheduled_latches_.empty() && scheduled_latches_.begin()->first <= target;
      if (latch_due && (!task_due || scheduled_latches_.begin()->first <= *task_due)) {
        fire_scheduled_latch();
        continue;
      }
      if (task_due && *task_due <= target && scheduler_.run_one(target)) {
        ++ran;
        continue;
      }
      break;
    }
    clock_.set_us(target);
    return ran;
  }
  // Runs whatever is due now (posted tasks, expired timers), including what those post. Returns how many ran.
  std::size_t run_pending() { return advance(std::chrono::microseconds(0)); }
  std::int64_t now_us() const noexcept { return clock_.now_us(); }
  ManualClock& clock() noexcept { return clock_; }
  // While on, Worker::cancel() loses the race (returns false) and the timer still runs: tests that an old timer
  // cannot stop a newer command rely on a generation check, not on cancel().
  void simulate_cancel_race(bool on) noexcept { scheduler_.set_cancel_race(on); }
  std::size_t pending_tasks() const { return scheduler_.size(); }
  // "<worker>: <message>" for every task that threw (the kernel logs these and marks the plugin failed).
  const std::vector<std::string>& task_failures() const noexcept { return task_failures_; }
  // Settings keys the kernel's rule left out with a warning ("drivers[0].frequency": unknown, no near miss of a key
  // the plugin's schema names), in the order instances were added.
  const std::vector<std::string>& ignored_settings() const noexcept { return ignored_settings_; }

  // ---- inspection ------------------------------------------------------------------------------------------

  const std::vector<std::string>& log_lines() const noexcept { return sink_.lines(); }
  MotionGate& motion() noexcept { return gate_; }
  EstopView& estop() noexcept { return estop_; }
  // ---- services (PluginContext::offer_service and service(); the rules are in rcand/sdk/services.hpp) ----------

  // The test offers a service itself, say a fake PoseSource: sdk::offer<PoseSource>(host, fake). Refused (false,
  // logged) like an instance's offer when the id is taken. Not owned: it must outlive the host.
  bool offer_service(std::string_view interface_id, const void* service) noexcept { return offer_as("", interface_id, service); }
  // What find<T>() answers every instance, so sdk::find<PoseSource>(host) checks what a plugin offered. Null when
  // nothing offers the id, or its instance failed.
  const void* service(std::string_view interface_id) const noexcept {
    std::lock_guard lock(services_mutex_);
    const auto it = services_.find(interface_id);
    if (it == services_.end() || instance_failed(it->second.owner)) return nullptr;
    return it->second.object;
  }
  // What find<ObstacleSource>() and PluginContext::obstacles() return (null: none), replacing any earlier offer of
  // it, the test's or an instance's. Not owned.
  void set_obstacle_source(const ObstacleSource* source) noexcept {
    std::lock_guard lock(services_mutex_);
    if (const auto it = services_.find(ObstacleSource::kServiceId); it != services_.end()) services_.erase(it);
    if (source) services_.emplace(std::string(ObstacleSource::kServiceId), ServiceOffer{source, ""});
  }

  // ---- R2R (find<R2rLinks>(ctx), and the deprecated PluginContext::r2r()) ------------------------------------

  struct R2rSent {
    std::string instance;  // who sent it: the `who` of R2rLinks::make_link (the instance id for PluginContext::r2r())
    std::string type;
    nlohmann::json payload;
    std::optional<std::string> target;
  };
  // find<R2rLinks>() and PluginContext::r2r() are null (a robot without R2R) until this is called.
  void enable_r2r() {
    std::lock_guard lock(services_mutex_);
    services_.emplace(std::string(R2rLinks::kServiceId), ServiceOffer{static_cast<const R2rLinks*>(&r2r_links_), ""});
  }
  // What instances sent, in order. The fake checks the type and that the payload is an object; the kernel also
  // checks each type's payload fields (docs/protocol.md §11).
  const std::vector<R2rSent>& r2r_sent() const noexcept { return r2r_sent_; }
  // Queues `message` for every subscription of its type on the subscriber's "r2r" worker, as the kernel does for a
  // validated message; run it with run_pending() or advance(). Returns how many subscriptions it was queued for.
  std::size_t deliver_r2r(const R2rMessage& message) {
    std::size_t queued = 0;
    for (const auto& [id, sub] : r2r_subscriptions_) {
      if (sub.type != message.type) continue;
      sub.worker->post([callback = sub.callback, message] { callback(message); });
      ++queued;
    }
    return queued;
  }
  // The cost function an instance installed (empty: the kernel's default).
  const R2rCostFunction& r2r_cost_function() const noexcept { return r2r_cost_; }
  // Later sends fail with `error` ("R2R is not running on this robot"); an empty string makes them succeed again.
  void fail_r2r_sends(std::string error) { r2r_send_error_ = std::move(error); }

  // ---- published statuses (PluginContext::publish_status) -----------------------------------------------------

  // What an instance (a driver id or capability name) published, oldest first. The kernel keeps only the latest and
  // serves it in GET /api/status; compare it with status() to check the plugin publishes what it reports.
  std::vector<nlohmann::json> published_statuses(std::string_view instance_id) const {
    std::lock_guard lock(published_mutex_);
    const auto it = published_.find(instance_id);
    return it == published_.end() ? std::vector<nlohmann::json>{} : it->second;
  }
  // The latest of those, or nullopt when the instance never published.
  std::optional<nlohmann::json> last_published_status(std::string_view instance_id) const {
    std::lock_guard lock(published_mutex_);
    const auto it = published_.find(instance_id);
    if (it == published_.end() || it->second.empty()) return std::nullopt;
    return it->second.back();
  }

  template <class T> T& driver(std::string_view id) {
    DriverSlot* slot = find_driver(id);
    if (!slot) throw HostError("no driver '" + std::string(id) + "'");
    auto* typed = dynamic_cast<T*>(slot->instance.get());
    if (!typed) throw HostError("driver '" + std::string(id) + "' is not of the requested type");
    return *typed;
  }
  template <class T> T& capability(std::string_view name) {
    CapabilitySlot* slot = find_capability(name);
    if (!slot) throw HostError("no capability '" + std::string(name) + "'");
    auto* typed = dynamic_cast<T*>(slot->instance.get());
    if (!typed) throw HostError("capability '" + std::string(name) + "' is not of the requested type");
    return *typed;
  }
  // The context handed to a driver or capability instance (by driver id or capability name).
  PluginContext& context(std::string_view instance_id) {
    if (auto* d = find_driver(instance_id)) return *d->context;
    if (auto* c = find_capability(instance_id)) return *c->context;
    throw HostError("no instance '" + std::string(instance_id) + "'");
  }
  bool driver_failed(std::string_view id) const {
    for (const auto& slot : drivers_)
      if (slot->id == id) return slot->failed.load();
    throw HostError("no driver '" + std::string(id) + "'");
  }
  bool capability_failed(std::string_view name) const {
    for (const auto& slot : capabilities_)
      if (slot->name == name) return slot->failed;
    throw HostError("no capability '" + std::string(name) + "'");
  }
  // How many of the capability's request handlers threw (each answered 500 INTERNAL; it stays in service).
  std::uint64_t handler_errors(std::string_view name) const {
    for (const auto& slot : capabilities_)
      if (slot->name == name) return slot->handler_errors;
    throw HostError("no capability '" + std::string(name) + "'");
  }

 private:
  class Context;
  struct CapabilityRegistration {
    CapabilityInfo info;
    CapabilityFactory factory;
    std::string plugin_id;
  };
  struct DriverRegistration {
    DriverInfo info;
    DriverFactory factory;
    std::string plugin_id;
  };

  // Member order is destruction order in reverse: the instance goes before its context.
  struct DriverSlot {
    std::string id;
    std::unique_ptr<Context> context;
    std::unique_ptr<Driver> instance;
    ActuatorDriver* actuator = nullptr;
    std::atomic<bool> failed{false};
  };
  struct CapabilitySlot {
    std::string name;
    bool custom = false;
    bool failed = false;
    std::uint64_t handler_errors = 0;  // request handlers that threw (each answered 500; the instance stays)
    std::unique_ptr<Context> context;
    std::unique_ptr<Capability> instance;
    std::vector<Route> routes;
  };

  // ---- the kernel services a plugin sees -------------------------------------------------------------------

  class Estop final : public EstopView {
   public:
    explicit Estop(FakeHost& host) : host_(host) {}
    bool latched() const noexcept override { return latched_.load(); }
    bool sleep_unless_latched(std::chrono::microseconds duration) const override {
      if (latched()) return false;
      const std::int64_t end = host_.clock_.now_us() + std::max<std::int64_t>(0, duration.count());
      if (!host_.scheduled_latches_.empty() && host_.scheduled_latches_.begin()->first <= end) {
        host_.fire_scheduled_latch();
        return false;
      }
      host_.clock_.set_us(end);
      return !latched();
    }
    void request_estop(const std::string& reason) noexcept override {
      latched_ = true;
      ++epoch_;
      host_.kernel_log_.warn("e-stop latched: ", reason);
      for (auto& slot : host_.drivers_)
        if (slot->actuator) slot->actuator->halt();
      for (auto& slot : host_.capabilities_) slot->instance->on_estop();
    }

   private:
    friend class FakeHost;
    FakeHost& host_;
    std::atomic<bool> latched_{false};
    std::atomic<std::uint64_t> epoch_{0};  // bumped by every latch, so the gate sees a latch+clear mid-command
  };

  class Gate final : public MotionGate {
   public:
    explicit Gate(FakeHost& host) : host_(host) {}
    GateStatus actuate(std::string_view actuator_id, const std::function<void(ActuatorDriver&)>& command) override {
      if (host_.estop_.latched()) return GateStatus::EstopActive;
      DriverSlot* slot = host_.find_driver(actuator_id);
      if (!slot || !slot->actuator) return GateStatus::UnknownActuator;
      if (slot->failed) return GateStatus::ActuatorFailed;
      const std::uint64_t epoch = host_.estop_.epoch_.load();
      try {
        command(*slot->actuator);
      } catch (const std::exception& e) {
        return fail(*slot, e.what());
      } catch (...) {
        return fail(*slot, "unknown exception");
      }
      // A latch that happened while the command ran: the command may have undone the halt, so halt again.
      if (host_.estop_.latched() || host_.estop_.epoch_.load() != epoch) {
        slot->actuator->halt();
        return GateStatus::EstopActive;  // as the kernel: the command was overtaken by a stop
      }
      return GateStatus::Ok;
    }
    GateStatus inspect(std::string_view actuator_id, const std::function<void(const ActuatorDriver&)>& reader) const override {
      const DriverSlot* slot = host_.find_driver(actuator_id);
      if (!slot || !slot->actuator) return GateStatus::UnknownActuator;
      if (slot->failed) return GateStatus::ActuatorFailed;
      reader(*slot->actuator);
      return GateStatus::Ok;
    }
    void halt(std::string_view actuator_id) noexcept override {
      if (DriverSlot* slot = host_.find_driver(actuator_id); slot && slot->actuator) slot->actuator->halt();
    }
    std::vector<ActuatorInfo> actuators() const override {
      std::vector<ActuatorInfo> out;
      for (const auto& slot : host_.drivers_)
        if (slot->actuator) out.push_back({slot->id, std::string(slot->actuator->interface_name())});
      return out;
    }

   private:
    // The driver threw: out of service, and halted in case it stopped half-way.
    GateStatus fail(DriverSlot& slot, const std::string& what) {
      slot.failed = true;
      host_.kernel_log_.error("driver '", slot.id, "' threw and is marked failed: ", what);
      slot.actuator->halt();
      return GateStatus::ActuatorFailed;
    }
    FakeHost& host_;
  };

  class R2rFake final : public R2rLink {
   public:
    R2rFake(FakeHost& host, Worker& worker, std::string who) : host_(host), worker_(worker), instance_(std::move(who)) {}
    ~R2rFake() override {
      std::erase_if(host_.r2r_subscriptions_, [this](const auto& entry) { return entry.second.link == this; });
    }
    R2rSendResult send(std::string_view type, const Json& payload, const std::optional<std::string>& target) override {
      if (!known(type)) return {false, "unknown R2R message type '" + std::string(type) + "'", "/type"};
      if (!payload.is_object()) return {false, "payload must be an object", "/payload"};
      if (!host_.r2r_send_error_.empty()) return {false, host_.r2r_send_error_, ""};
      host_.r2r_sent_.push_back({instance_, std::string(type), payload, target});
      return {true, "", ""};
    }
    std::uint64_t subscribe(std::string_view type, Callback callback) override {
      if (!known(type)) throw std::invalid_argument("unknown R2R message type '" + std::string(type) + "'");
      if (!callback) throw std::invalid_argument("R2R subscribe needs a callback");
      const std::uint64_t id = ++host_.r2r_next_id_;
      host_.r2r_subscriptions_[id] = {this, &worker_, std::string(type), std::move(callback)};
      return id;
    }
    void unsubscribe(std::uint64_t id) noexcept override { host_.r2r_subscriptions_.erase(id); }
    void set_cost_function(R2rCostFunction cost) override { host_.r2r_cost_ = std::move(cost); }

   private:
    static bool known(std::string_view type) {
      for (std::string_view t : {"status", "task_request", "task_response", "command", "negotiation", "error"})
        if (t == type) return true;
      return false;
    }
    FakeHost& host_;
    Worker& worker_;
    std::string instance_;
  };

  class R2rLinksFake final : public R2rLinks {
   public:
    explicit R2rLinksFake(FakeHost& host) : host_(host) {}
    std::unique_ptr<R2rLink> make_link(Worker& worker, std::string_view who) const noexcept override {
      try {
        return std::make_unique<R2rFake>(host_, worker, std::string(who));
      } catch (...) {
        return nullptr;
      }
    }

   private:
    FakeHost& host_;
  };

  class Context final : public PluginContext {
   public:
    Context(FakeHost& host, std::string plugin_id, std::string instance_id, nlohmann::json settings)
        : host_(host),
          plugin_id_(std::move(plugin_id)),
          instance_id_(std::move(instance_id)),
          config_(std::move(settings)),
          logger_(host.sink_, "plugin." + plugin_id_) {}
    std::string_view plugin_id() const noexcept override { return plugin_id_; }
    std::string_view instance_id() const noexcept override { return instance_id_; }
    Logger& log() noexcept override { return logger_; }
    const Clock& clock() const noexcept override { return host_.clock_; }
    EstopView& estop() noexcept override { return host_.estop_; }
    MotionGate& motion() noexcept override { return host_.gate_; }
    const ConfigView& config() const noexcept override { return config_; }
    const ConfigView& robot_config() const noexcept override { return host_.robot_config_; }
    Worker& worker(std::string_view name) override { return host_.worker_for(instance_id_, name); }
    const ObstacleSource* obstacles() const noexcept override { return find<ObstacleSource>(host_); }
    R2rLink* r2r() noexcept override {
      const auto* links = find<R2rLinks>(host_);
      if (links == nullptr) return nullptr;
      if (!r2r_) r2r_ = links->make_link(worker("r2r"), instance_id_);
      return r2r_.get();
    }
    // Any thread, as in the kernel: recorded under a lock; an allocation failure loses the record, never throws.
    void publish_status(const Json& status) noexcept override {
      try {
        std::lock_guard lock(host_.published_mutex_);
        host_.published_[instance_id_].push_back(status);
      } catch (...) {
      }
    }
    const void* service(std::string_view interface_id) const noexcept override { return host_.service(interface_id); }
    bool offer_service(std::string_view interface_id, const void* service) noexcept override {
      return host_.offer_as(instance_id_, interface_id, service);
    }

   private:
    FakeHost& host_;
    std::unique_ptr<R2rLink> r2r_;
    std::string plugin_id_;
    std::string instance_id_;
    ConfigView config_;
    RecordingLogger logger_;
  };

  // Stages what one register function adds; the host keeps it only if the whole registration succeeds.
  class Recorder final : public Registrar {
   public:
    explicit Recorder(const FakeHost& host, std::string plugin_id) : host_(host), plugin_id_(std::move(plugin_id)) {}
    void add_capability(CapabilityInfo info, CapabilityFactory factory) override {
      if (closed) throw std::logic_error("add_capability called outside the register function");
      if (info.name.empty()) throw std::invalid_argument("add_capability: empty capability name");
      if (!factory) throw std::invalid_argument("add_capability(" + info.name + "): null factory");
      if (capabilities.count(info.name) || host_.capability_registrations_.count(info.name))
        throw std::invalid_argument("capability '" + info.name + "' is registered twice");
      const std::string name = info.name;
      capabilities.emplace(name, CapabilityRegistration{std::move(info), std::move(factory), plugin_id_});
    }
    void add_driver(DriverInfo info, DriverFactory factory) override {
      if (closed) throw std::logic_error("add_driver called outside the register function");
      if (info.protocol.empty()) throw std::invalid_argument("add_driver: empty protocol");
      if (!factory) throw std::invalid_argument("add_driver(" + info.protocol + "): null factory");
      if (info.actuates && info.interface.empty())
        throw std::invalid_argument("add_driver(" + info.protocol + "): an actuating driver must name its interface");
      if (drivers.count(info.protocol) || host_.driver_registrations_.count(info.protocol))
        throw std::invalid_argument("driver protocol '" + info.protocol + "' is registered twice");
      const std::string protocol = info.protocol;
      drivers.emplace(protocol, DriverRegistration{std::move(info), std::move(factory), plugin_id_});
    }

    bool closed = false;
    std::map<std::string, CapabilityRegistration, std::less<>> capabilities;
    std::map<std::string, DriverRegistration, std::less<>> drivers;

   private:
    const FakeHost& host_;
    std::string plugin_id_;
  };

  // ---- loading ---------------------------------------------------------------------------------------------

  void load_impl(rcand_plugin_entry_fn entry, const nlohmann::json* manifest) {
    if (!entry) throw LoadError("failed-to-open: the entry function is null");
    const rcand_plugin_descriptor* d = entry();
    if (!d) throw LoadError("failed-to-open: the entry function returned no descriptor");
    if (d->magic != RCAND_DESCRIPTOR_MAGIC) throw LoadError("incompatible-abi: bad descriptor magic (not an rcand plugin)");
    if (d->struct_size > sizeof(rcand_plugin_descriptor))
      throw LoadError("incompatible-abi: descriptor is " + std::to_string(d->struct_size) + " bytes, larger than this host's " +
                      std::to_string(sizeof(rcand_plugin_descriptor)) + " (built against a newer SDK)");
    if (d->struct_size < sizeof(rcand_plugin_descriptor))  // the 1.0 layout is the current one
      throw LoadError("incompatible-abi: descriptor is " + std::to_string(d->struct_size) +
                      " bytes, smaller than the ABI 1.0 layout");
    if (d->abi_major != RCAND_ABI_MAJOR)
      throw LoadError("incompatible-abi: built for ABI " + std::to_string(d->abi_major) + ", host speaks " +
                      std::to_string(RCAND_ABI_MAJOR));
    if (d->abi_minor > RCAND_ABI_MINOR)
      throw LoadError("incompatible-abi: built for ABI " + std::to_string(d->abi_major) + "." + std::to_string(d->abi_minor) +
                      ", newer than the host's " + std::to_string(RCAND_ABI_MAJOR) + "." + std::to_string(RCAND_ABI_MINOR));
    if (!d->plugin_id || !*d->plugin_id) throw LoadError("incompatible-abi: the descriptor has no plugin id");
    if (!d->version || !*d->version) throw LoadError("incompatible-abi: the descriptor has no version");
    if (!d->register_plugin) throw LoadError("incompatible-abi: the descriptor has no register function");
    const std::string id = d->plugin_id;
    if (loaded_.count(id)) throw LoadError("duplicate plugin id '" + id + "'");
    if (manifest) check_manifest_identity(*manifest, id, d->version);
    if (manifest) {  // the kernel's manifest check, from the same contract
      try {
        if (manifest->contains("config")) contract::check_settings_schema(manifest->at("config"), "config.");
        const auto provides = manifest->value("provides", nlohmann::json::array());
        for (std::size_t i = 0; i < provides.size(); ++i)
          if (provides[i].is_object()) contract::check_provided_item(provides[i], "provides[" + std::to_string(i) + "]");
      } catch (const contract::SettingsError& e) {
        throw LoadError(std::string("invalid-manifest: ") + e.what());
      }
    }

    Recorder recorder(*this, id);
    try {
      d->register_plugin(reinterpret_cast<rcand_registrar*>(static_cast<Registrar*>(&recorder)));
    } catch (const std::exception& e) {
      throw LoadError("registration-failed: " + id + ": " + e.what());
    } catch (...) {
      throw LoadError("registration-failed: " + id + ": unknown exception");
    }
    recorder.closed = true;
    if (manifest) check_provides(*manifest, id, recorder);

    loaded_.insert(id);
    if (manifest) manifests_[id] = *manifest;  // its settings schemas: none means the plugin takes no settings
    for (auto& [name, reg] : recorder.capabilities) capability_registrations_.emplace(name, std::move(reg));
    for (auto& [protocol, reg] : recorder.drivers) driver_registrations_.emplace(protocol, std::move(reg));
  }

  static void check_manifest_identity(const nlohmann::json& m, const std::string& id, const std::string& version) {
    if (!m.is_object()) throw LoadError("manifest-mismatch: the manifest is not a JSON object");
    if (m.value("id", std::string()) != id)
      throw LoadError("manifest-mismatch: descriptor id '" + id + "' != manifest id '" + m.value("id", std::string()) + "'");
    if (m.value("version", std::string()) != version)
      throw LoadError("manifest-mismatch: descriptor version '" + version + "' != manifest version '" +
                      m.value("version", std::string()) + "'");
  }

  // Registered items must equal the manifest's "provides" (kind, name, actuates, interface), as a set.
  static void check_provides(const nlohmann::json& m, const std::string& id, const Recorder& r) {
    using Item = std::tuple<std::string, std::string, bool, std::string>;
    std::set<Item> declared, registered;
    const auto provides = m.find("provides");
    if (provides == m.end() || !provides->is_array()) throw LoadError("manifest-mismatch: " + id + ": no provides[] array");
    for (const auto& p : *provides) {
      if (!p.is_object() || !p.contains("kind") || !p.contains("name"))
        throw LoadError("manifest-mismatch: " + id + ": provides[] items need kind and name");
      declared.emplace(p.value("kind", std::string()), p.value("name", std::string()), p.value("actuates", false),
                       p.value("interface", std::string()));
    }
    for (const auto& [name, reg] : r.capabilities) registered.emplace("capability", name, reg.info.actuates, "");
    for (const auto& [protocol, reg] : r.drivers) registered.emplace("driver", protocol, reg.info.actuates, reg.info.interface);
    if (declared != registered) {
      auto describe = [](const std::set<Item>& items) {
        std::string out;
        for (const auto& [kind, name, actuates, interface] : items)
          out += (out.empty() ? "" : ", ") + kind + " " + name + (actuates ? " (actuates" : " (") +
                 (interface.empty() ? "" : " " + interface) + ")";
        return out.empty() ? std::string("nothing") : out;
      };
      throw LoadError("manifest-mismatch: " + id + " registered " + describe(registered) + " but its manifest provides " +
                      describe(declared));
    }
  }

  // The kernel's settings rule (rcand/sdk/contract/settings.hpp): types, bounds, enums and required keys checked,
  // defaults filled in; in a driver entry every unknown key is refused, elsewhere near-miss unknown keys are refused
  // with a did-you-mean and other unknown keys left out and recorded (ignored_settings(); rcand logs a warning). A
  // driver's claims (the pins, channels, ids its settings name) must not repeat within it or another driver's.
  // `where` names the instance in the error.
  nlohmann::json apply_schema(const std::string& plugin_id, std::string_view kind, const std::string& name,
                              nlohmann::json settings, const std::string& where) {
    const auto it = manifests_.find(plugin_id);
    if (it == manifests_.end()) return settings;  // loaded without a manifest: nothing to check against
    const bool driver = kind == "driver";
    auto result = contract::validate_settings(
        contract::item_settings_schema(it->second, kind, name), settings,
        contract::SettingsRules{
            driver ? std::span<const std::string_view>(contract::kDriverEntryKeys) : std::span<const std::string_view>(),
            driver ? contract::UnknownKeys::Refuse : contract::UnknownKeys::WarnUnlessNearMiss});
    if (!result.problems.empty()) {
      const auto& [key, problem] = result.problems.front();
      throw HostError((key.empty() ? where : where + (key.front() == '[' ? "" : ".") + key) + ": " + problem +
                      " (settings of plugin " + plugin_id + ")");
    }
    for (const auto& key : result.ignored) ignored_settings_.push_back(where + "." + key);
    if (driver) {
      auto claims = driver_claims_;
      claims.push_back({where, "driver " + name, result.claims});
      for (const auto& conflict : contract::claim_conflicts(claims))
        if (conflict.instance + 1 == claims.size()) throw HostError(where + "." + conflict.key + ": " + conflict.problem);
      driver_claims_ = std::move(claims);
    }
    return std::move(result.settings);
  }

  template <class Map> static std::string known(const Map& map) {
    std::string out;
    for (const auto& [name, reg] : map) out += (out.empty() ? "" : ", ") + name;
    return out.empty() ? " (none loaded)" : " (known: " + out + ")";
  }

  // Roughly what the kernel enforces on routes at registration.
  void check_routes(const CapabilitySlot& slot) const {
    for (const auto& route : slot.routes) {
      const std::string what = "capability '" + slot.name + "' route " + route.method + " " + route.path;
      if (!route.handler) throw HostError(what + ": no handler");
      if (route.method.empty()) throw HostError(what + ": no method");
      if (!slot.custom && (route.path.empty() || route.path.front() != '/')) throw HostError(what + ": path must be absolute");
      if (slot.custom && !route.path.empty() && route.path.front() != '/')
        throw HostError(what + ": a custom path starts with '/' or is empty");
      if (!slot.custom && route.path == "/api/action") {
        if (route.action_type.empty()) throw HostError(what + ": an /api/action route needs action_type");
        if (find_action(route.action_type).first)
          throw HostError(what + ": action type '" + route.action_type + "' is already served");
      }
    }
  }

  // ---- dispatch --------------------------------------------------------------------------------------------

  std::pair<CapabilitySlot*, const Route*> find_action(std::string_view type) const {
    for (const auto& slot : capabilities_)
      if (!slot->custom)
        for (const auto& route : slot->routes)
          if (route.path == "/api/action" && route.method == "POST" && route.action_type == type) return {slot.get(), &route};
    return {nullptr, nullptr};
  }

  Response dispatch(std::string method, std::string target, nlohmann::json body, Role role,
                    std::optional<std::vector<Scope>> scopes) {
    Request request;
    request.method = method;
    const auto q = target.find('?');
    request.path = target.substr(0, q);
    if (q != std::string::npos) {  // no percent-decoding: tests pass plain values
      std::string_view rest = std::string_view(target).substr(q + 1);
      while (!rest.empty()) {
        const auto amp = rest.find('&');
        const std::string_view pair = rest.substr(0, amp);
        const auto eq = pair.find('=');
        request.query[std::string(pair.substr(0, eq))] = eq == std::string_view::npos ? "" : std::string(pair.substr(eq + 1));
        rest = amp == std::string_view::npos ? std::string_view{} : rest.substr(amp + 1);
      }
    }
    request.body = std::move(body);
    request.principal = "test";
    request.role = role;
    request.message_id = "fake-" + std::to_string(++message_counter_);
    request.scopes = scopes ? std::move(*scopes) : default_scopes_of(role);
    auto credential = std::make_shared<TestCredential>();
    credential->principal = request.principal;
    credential->role = role;
    request.credential = std::move(credential);

    // The kernel's door, from the same contract (rcand/sdk/contract/door.hpp): match, decide, then serve.
    namespace contract = rcand::sdk::contract;
    if (request.path.rfind(contract::kCustomPrefix, 0) == 0) {
      const std::string_view rest = std::string_view(request.path).substr(contract::kCustomPrefix.size());
      const auto slash = rest.find('/');
      request.subpath = slash == std::string_view::npos ? "" : std::string(rest.substr(slash));
    }
    const std::vector<contract::RouteRow> table = route_table().rows;
    const auto found = contract::match(table, method, request.path);
    if (found.row == nullptr) {
      if (found.allowed.empty()) return Response::error(404, "NOT_FOUND", "no endpoint " + bounded_text(request.path));
      return contract::method_not_allowed(method, request.path, found.allowed);
    }
    const contract::Caller caller{"role " + std::string(role_name(role)), request.scopes};
    const contract::RouteRow* row = found.row;
    if (auto verdict = contract::decide(caller, *row, estop_.latched()); !verdict.run) return verdict.refusal;
    if (row->kind == contract::RowKind::Action) {
      std::vector<std::string> declared_types;
      for (const auto& cap : contract::standard_capabilities())
        if (find_capability(cap.name) != nullptr)
          for (auto type : cap.action_types) declared_types.emplace_back(type);
      Response refusal;
      const std::string type = contract::action_type_of(request.body, declared_types, refusal);
      if (refusal.status != 200) return refusal;
      row = contract::match(table, "POST", contract::kActionPath, type).row;
    }
    std::string subpath;
    const std::string capability = contract::unserved_capability(row->capability, request.path, &subpath);
    const bool custom = request.path.rfind(contract::kCustomPrefix, 0) == 0;
    if (custom && contract::find_standard(capability) != nullptr)
      return Response::error(404, "NOT_FOUND",
                             "'" + bounded_text(capability) + "' is a standard capability; use its standard endpoint");
    CapabilitySlot* slot = find_capability(capability);
    if (slot == nullptr || slot->custom != custom) {
      std::vector<std::string> declared;
      for (const auto& s : capabilities_) declared.push_back(s->name);
      return contract::not_declared(capability, declared);
    }
    const Route* route = nullptr;
    std::vector<std::string> methods;  // the methods the path has, for a 405
    for (const auto& r : slot->routes) {
      if (row->kind != contract::RowKind::Unserved && r.method == row->method && r.path == row->route_path &&
          r.action_type == row->action_type)
        route = &r;
      if (r.action_type.empty() && r.path == (custom ? subpath : request.path)) methods.push_back(r.method);
    }
    if (route == nullptr) {
      if (!row->action_type.empty()) return contract::no_endpoint(slot->name, request.path);
      return contract::no_route(slot->name, method, request.path, methods);
    }
    if (!row->action_type.empty())  // an action type's own row, known once the body's type is
      if (auto verdict = contract::decide(caller, *row, estop_.latched()); !verdict.run) return verdict.refusal;
    // As the kernel (docs/protocol.md §7.16): a throw fails this request only, counted in handler_errors().
    try {
      return contract::normalized(route->handler(request));
    } catch (const std::exception& e) {
      ++slot->handler_errors;
      kernel_log_.error("capability '", slot->name, "' request handler threw: ", e.what());
    } catch (...) {
      ++slot->handler_errors;
      kernel_log_.error("capability '", slot->name, "' request handler threw");
    }
    return contract::handler_threw(slot->name);
  }

  // ---- services ----------------------------------------------------------------------------------------------

  // `owner`: the offering instance (driver id or capability name), "" for the test.
  bool offer_as(const std::string& owner, std::string_view interface_id, const void* service) noexcept {
    try {
      const std::string who = owner.empty() ? std::string("the test") : "instance '" + owner + "'";
      if (interface_id.empty() || !service) {
        kernel_log_.error(who, ": offer of service '", interface_id,
                          "' refused: ", interface_id.empty() ? "empty id" : "null object");
        return false;
      }
      std::lock_guard lock(services_mutex_);
      if (!services_.emplace(std::string(interface_id), ServiceOffer{service, owner}).second) {
        kernel_log_.error(who, ": offer of service '", interface_id, "' refused: already offered (one provider per service)");
        return false;
      }
      return true;
    } catch (...) {
      return false;
    }
  }
  void withdraw_offers(const std::string& owner) noexcept {
    std::lock_guard lock(services_mutex_);
    std::erase_if(services_, [&owner](const auto& entry) { return entry.second.owner == owner; });
  }
  bool instance_failed(const std::string& owner) const noexcept {
    if (const DriverSlot* d = owner.empty() ? nullptr : find_driver(owner)) return d->failed.load();
    if (const CapabilitySlot* c = owner.empty() ? nullptr : find_capability(owner)) return c->failed;
    return false;
  }

  // ---- lookups ---------------------------------------------------------------------------------------------

  DriverSlot* find_driver(std::string_view id) const {
    for (const auto& slot : drivers_)
      if (slot->id == id) return slot.get();
    return nullptr;
  }
  CapabilitySlot* find_capability(std::string_view name) const {
    for (const auto& slot : capabilities_)
      if (slot->name == name) return slot.get();
    return nullptr;
  }

  Worker& worker_for(const std::string& instance, std::string_view name) {
    const bool valid = !name.empty() && name.size() <= 64 && std::all_of(name.begin(), name.end(), [](char c) {
      return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' || c == '-' || c == '.';
    });
    if (!valid) throw std::invalid_argument("invalid worker name '" + std::string(name) + "' (use 1-64 of [A-Za-z0-9_.-])");
    const std::string full = instance + "." + std::string(name);
    auto& worker = workers_[full];
    if (!worker) worker = std::make_unique<FakeWorker>(scheduler_, clock_, full);
    return *worker;
  }

  void fire_scheduled_latch() {
    auto node = scheduled_latches_.extract(scheduled_latches_.begin());
    clock_.set_us(node.key());
    estop_.request_estop(node.mapped());
  }

  // Declaration order matters: services before the instances that use them.
  ConfigView robot_config_;
  struct ServiceOffer {
    const void* object = nullptr;
    std::string owner;  // the offering instance; "" for the test
  };
  mutable std::mutex services_mutex_;  // offers and finds may come from any thread
  std::map<std::string, ServiceOffer, std::less<>> services_;
  struct R2rSubscription {
    const R2rFake* link;
    Worker* worker;  // the link's: where its callbacks run
    std::string type;
    R2rLink::Callback callback;
  };
  R2rLinksFake r2r_links_{*this};
  std::vector<R2rSent> r2r_sent_;
  std::map<std::uint64_t, R2rSubscription> r2r_subscriptions_;
  std::uint64_t r2r_next_id_ = 0;
  mutable std::mutex published_mutex_;  // publish_status() may come from any thread
  std::map<std::string, std::vector<nlohmann::json>, std::less<>> published_;
  R2rCostFunction r2r_cost_;
  std::string r2r_send_error_;
  ManualClock clock_;
  LogSink sink_;
  FakeScheduler scheduler_;
  RecordingLogger kernel_log_;
  Estop estop_;
  Gate gate_;
  std::multimap<std::int64_t, std::string> scheduled_latches_;
  std::vector<std::string> task_failures_;
  std::uint64_t message_counter_ = 0;
  std::set<std::string> loaded_;
  std::map<std::string, nlohmann::json> manifests_;
  std::vector<std::string> ignored_settings_;
  std::vector<contract::InstanceClaims> driver_claims_;  // every driver's claims, for the next one's check
  std::map<std::string, CapabilityRegistration, std::less<>> capability_registrations_;
  std::map<std::string, DriverRegistration, std::less<>> driver_registrations_;
  std::map<std::string, std::unique_ptr<FakeWorker>> workers_;
  std::vector<std::unique_ptr<DriverSlot>> drivers_;
  std::vector<std::unique_ptr<CapabilitySlot>> capabilities_;
};

}  // namespace rcand::sdk::testing
