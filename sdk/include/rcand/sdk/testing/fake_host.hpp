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
#include "rcand/sdk/contract/isolation.hpp"
#include "rcand/sdk/contract/plan.hpp"
#include "rcand/sdk/contract/requests.hpp"
#include "rcand/sdk/contract/settings.hpp"
#include "rcand/sdk/driver.hpp"
#include "rcand/sdk/registrar.hpp"
#include "rcand/sdk/services.hpp"
#include "rcand/sdk/testing/fake_r2r.hpp"
#include "rcand/sdk/testing/fake_registry.hpp"
#include "rcand/sdk/testing/fake_scheduler.hpp"
#include "rcand/sdk/testing/fake_services.hpp"
#include "rcand/sdk/testing/manual_clock.hpp"
#include "rcand/sdk/testing/recording_logger.hpp"

namespace rcand::sdk::testing {

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
      services_.withdraw((*it)->name);
      (*it)->instance->shutdown();
    }
    for (auto it = drivers_.rbegin(); it != drivers_.rend(); ++it) {
      services_.withdraw((*it)->id);
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
  void load(rcand_plugin_entry_fn entry) { registry_.load(entry, nullptr); }

  // As load(entry), and also checks the plugin against its manifest as the kernel does: id and version equal,
  // registrations equal to "provides", a well-formed "config" schema; instance settings are then validated against
  // that schema (none: the plugin takes no settings), with defaults filled in, before each factory runs. The config
  // rules are the kernel's own (rcand/sdk/contract/settings.hpp).
  void load(rcand_plugin_entry_fn entry, const nlohmann::json& manifest) { registry_.load(entry, &manifest); }

  // ---- instances -------------------------------------------------------------------------------------------

  // One `drivers[]` entry: calls the protocol's factory (settings carry `id` and `protocol`), then start().
  Driver& add_driver(std::string id, std::string protocol, nlohmann::json settings = {}) {
    if (find_driver(id)) throw HostError("driver id '" + id + "' is already in use");
    const auto* reg = registry_.driver(protocol);
    if (reg == nullptr)
      throw HostError("no loaded plugin registers driver protocol '" + protocol + "'" + registry_.known_drivers());
    if (settings.is_null()) settings = nlohmann::json::object();
    if (!settings.is_object()) throw HostError("drivers[" + id + "]: settings must be an object");
    settings["id"] = id;
    settings["protocol"] = protocol;
    settings = apply_schema(reg->plugin_id, "driver", protocol, std::move(settings), "drivers[" + id + "]");

    auto slot = std::make_unique<DriverSlot>();
    slot->id = id;
    slot->context = std::make_unique<Context>(*this, reg->plugin_id, id, std::move(settings));
    try {
      slot->instance = reg->factory(*slot->context);
    } catch (const std::exception& e) {
      services_.withdraw(id);
      throw HostError("driver '" + id + "': factory threw: " + e.what());
    }
    if (!slot->instance) throw HostError("driver '" + id + "': factory returned null");
    if (reg->info.actuates) {
      slot->actuator = dynamic_cast<ActuatorDriver*>(slot->instance.get());
      if (!slot->actuator) throw HostError("driver '" + id + "': registered as actuating but the factory made no ActuatorDriver");
      if (slot->actuator->interface_name() != reg->info.interface)
        throw HostError("driver '" + id + "': registered interface '" + reg->info.interface + "' but the instance implements '" +
                        std::string(slot->actuator->interface_name()) + "'");
    }
    try {
      slot->instance->start();
    } catch (const std::exception& e) {
      services_.withdraw(id);
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
    const auto* reg = registry_.capability(name);
    if (reg == nullptr) throw HostError("no loaded plugin registers capability '" + name + "'" + registry_.known_capabilities());
    if (settings.is_null() || (settings.is_object() && settings.empty())) {
      const auto configured = robot_config_.sub("runtime.capabilities." + name).raw();
      settings = configured.is_object() ? configured : nlohmann::json::object();
    }
    if (!settings.is_object()) throw HostError("runtime.capabilities." + name + ": settings must be an object");
    settings = apply_schema(reg->plugin_id, "capability", name, std::move(settings), "runtime.capabilities." + name);

    auto slot = std::make_unique<CapabilitySlot>();
    slot->name = name;
    slot->custom = name.find('.') != std::string::npos;  // reverse-domain names are custom (§9)
    slot->context = std::make_unique<Context>(*this, reg->plugin_id, name, std::move(settings));
    try {
      slot->instance = reg->factory(*slot->context);
      if (!slot->instance) throw HostError("factory returned null");
      slot->instance->start();
      slot->routes = slot->instance->routes();
    } catch (const std::exception& e) {
      services_.withdraw(name);
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
  bool offer_service(std::string_view interface_id, const void* service) noexcept {
    return services_.offer("", interface_id, service);
  }
  // What find<T>() answers every instance, so sdk::find<PoseSource>(host) checks what a plugin offered. Null when
  // nothing offers the id, or its instance failed.
  const void* service(std::string_view interface_id) const noexcept {
    return services_.find(interface_id, [this](const std::string& owner) { return instance_failed(owner); });
  }
  // What find<ObstacleSource>() and PluginContext::obstacles() return (null: none), replacing any earlier offer of
  // it, the test's or an instance's. Not owned.
  void set_obstacle_source(const ObstacleSource* source) noexcept { services_.replace(ObstacleSource::kServiceId, source); }

  // ---- R2R (find<R2rLinks>(ctx), and the deprecated PluginContext::r2r()) ------------------------------------

  using R2rSent = FakeR2r::Sent;
  // find<R2rLinks>() and PluginContext::r2r() are null (a robot without R2R) until this is called.
  void enable_r2r() noexcept { services_.replace(R2rLinks::kServiceId, static_cast<const R2rLinks*>(&r2r_)); }
  // What instances sent, in order (FakeR2r::sent()).
  const std::vector<R2rSent>& r2r_sent() const noexcept { return r2r_.sent(); }
  // Queues `message` for every subscription of its type on the subscriber's "r2r" worker, as the kernel does for a
  // validated message; run it with run_pending() or advance(). Returns how many subscriptions it was queued for.
  std::size_t deliver_r2r(const R2rMessage& message) { return r2r_.deliver(message); }
  // The cost function an instance installed (empty: the kernel's default).
  R2rCostFunction r2r_cost_function() const { return r2r_.cost_function(); }
  // Later sends fail with `error` ("R2R is not running on this robot"); an empty string makes them succeed again.
  void fail_r2r_sends(std::string error) { r2r_.fail_sends(std::move(error)); }

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
      return host_.services_.offer(instance_id_, interface_id, service);
    }

   private:
    FakeHost& host_;
    std::unique_ptr<R2rLink> r2r_;
    std::string plugin_id_;
    std::string instance_id_;
    ConfigView config_;
    RecordingLogger logger_;
  };

  // The kernel's settings rule (rcand/sdk/contract/settings.hpp): types, bounds, enums and required keys checked,
  // defaults filled in; in a driver entry every unknown key is refused, elsewhere near-miss unknown keys are refused
  // with a did-you-mean and other unknown keys left out and recorded (ignored_settings(); rcand logs a warning). A
  // driver's claims (the pins, channels, ids its settings name) must not repeat within it or another driver's.
  // `where` names the instance in the error.
  nlohmann::json apply_schema(const std::string& plugin_id, std::string_view kind, const std::string& name,
                              nlohmann::json settings, const std::string& where) {
    const nlohmann::json* manifest = registry_.manifest(plugin_id);
    if (manifest == nullptr) return settings;  // loaded without a manifest: nothing to check against
    const bool driver = kind == "driver";
    const auto schema = contract::item_settings_schema(*manifest, kind, name);
    auto result = driver
                      ? contract::validate_settings(
                            schema, settings, contract::SettingsRules{contract::kDriverEntryKeys, contract::UnknownKeys::Refuse})
                      : contract::validate_capability_settings(schema, settings, contract::UnknownKeys::WarnUnlessNearMiss);
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
  FakeR2r r2r_;
  mutable std::mutex published_mutex_;  // publish_status() may come from any thread
  std::map<std::string, std::vector<nlohmann::json>, std::less<>> published_;
  ManualClock clock_;
  LogSink sink_;
  FakeScheduler scheduler_;
  RecordingLogger kernel_log_;
  FakeServiceDirectory services_{kernel_log_};
  Estop estop_;
  Gate gate_;
  std::multimap<std::int64_t, std::string> scheduled_latches_;
  std::vector<std::string> task_failures_;
  std::uint64_t message_counter_ = 0;
  std::vector<std::string> ignored_settings_;
  std::vector<contract::InstanceClaims> driver_claims_;  // every driver's claims, for the next one's check
  FakePluginRegistry registry_;
  std::map<std::string, std::unique_ptr<FakeWorker>> workers_;
  std::vector<std::unique_ptr<DriverSlot>> drivers_;
  std::vector<std::unique_ptr<CapabilitySlot>> capabilities_;
};

}  // namespace rcand::sdk::testing
