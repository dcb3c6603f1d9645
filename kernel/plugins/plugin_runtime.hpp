// Turns loaded plugins into running instances: one driver instance per `drivers[]` entry, one capability
// instance per declared capability, each with its own context, health and (for capabilities) handler worker.
//
// Destruction order matters: capability handler workers are joined first (no request runs any more), then
// capability objects and their contexts (their workers join), then driver objects; plugin libraries are never
// unloaded, so code outlives every object it made.
#pragma once

#include <atomic>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "kernel/plugins/instance_context.hpp"
#include "kernel/plugins/plugin_host.hpp"
#include "kernel/plugins/status_reader.hpp"
#include "kernel/safety/actuator_table.hpp"
#include "libs/base/bounded_call.hpp"
#include "libs/base/deadline_crew.hpp"
#include "libs/base/reload_gate.hpp"
#include "libs/config/robot_config.hpp"

namespace rcand::kernel {

inline constexpr std::size_t kNoStatus = static_cast<std::size_t>(-1);

struct DriverInstance {
  std::string id, protocol, plugin_id;
  std::string who;  // "plugin <id> driver <id>", for the trampoline's log lines
  bool actuates = false;
  std::string interface;  // actuating drivers: the interface their registration names, failed or not
  InstanceHealth health;
  std::unique_ptr<InstanceContext> context;
  std::unique_ptr<sdk::Driver> object;   // null when it could not be created
  std::size_t status_index = kNoStatus;  // its source in the status reader
};

struct CapabilityInstance {
  std::string name, plugin_id;
  std::string who;  // "plugin <id> capability <name>", for the trampoline's log lines
  bool actuates = false;
  std::vector<std::string> needs;  // the actuator interfaces its manifest requires: its state follows those drivers
  InstanceHealth health;
  std::unique_ptr<InstanceContext> context;
  std::unique_ptr<sdk::Capability> object;  // null when it could not be created
  std::vector<sdk::Route> routes;
  std::vector<sdk::StreamRoute> stream_routes;                        // ABI 1.2 plugins only (Capability::stream_routes())
  std::unique_ptr<WorkerThread> handler_worker;                       // "cap.<name>": handlers run here, one at a time
  std::size_t status_index = kNoStatus;                               // its source in the status reader
  std::shared_ptr<ReloadGate> gate = std::make_shared<ReloadGate>();  // closed while its plugin is reloaded
  // Declared and not up yet (its start() runs on the kernel's starter thread): requests answer 503 STARTING. Cleared
  // after every field above is set, so a thread that reads it false reads them whole.
  std::atomic<bool> starting{false};
  const RegisteredCapability* registered = nullptr;  // what declare_capabilities() found, for start_declared()
};

// What PluginRuntime::reload did: `error` empty when every instance of the plugin runs its new code again.
struct ReloadResult {
  int status = 200;  // the HTTP status to answer with
  std::string code;  // the error code when not 200
  std::string error;
  nlohmann::json instances = nlohmann::json::array();  // [{"driver"|"capability","state","reason"?}]
};

class PluginRuntime {
 public:
  PluginRuntime(PluginHost& host, KernelServices& services, ActuatorTable& actuators);
  ~PluginRuntime();

  // Main thread, at startup. Plugin settings that fail the manifest's config schema throw ConfigError (with the
  // config file's line and column); plugin code that throws marks only that instance failed.
  void start_drivers(const config::RobotConfig& config);
  void start_capabilities(const std::vector<std::string>& names, const config::RobotConfig& config) {
    declare_capabilities(names, config);
    start_declared(config, [] { return true; }, {});
  }
  // The same in two steps, so that rcand serves while capabilities start. Main thread, before serving: every capability
  // declared (its plugin found, its settings checked, a ConfigError thrown) and `starting`, no plugin code run. Then,
  // on one other thread, not concurrently with reload() or shutdown(): each one's factory, start() and routes() in
  // order, `up` called as each is up or failed; once `go_on` answers false the rest fail without starting.
  void declare_capabilities(const std::vector<std::string>& names, const config::RobotConfig& config);
  void start_declared(const config::RobotConfig& config, const std::function<bool()>& go_on,
                      const std::function<void(CapabilityInstance&)>& up);
  // Any thread, at shutdown: a capability's start() still running is abandoned now (as at plugin_start_timeout_ms).
  void give_up_starting() { start_waiter_->give_up(); }
  // rcand --check-config: what the two above would refuse or fail, found without creating any instance (no plugin
  // factory runs, no device is opened): a driver protocol or capability no loaded plugin serves (with a did-you-mean
  // over the installed ones), settings that fail the manifest's schema, an actuator interface a capability requires
  // and no configured driver provides, and plan_problems(). Every problem at its config position.
  std::vector<yaml::ConfigDiagnostic> check(const config::RobotConfig& config, const std::vector<std::string>& capabilities);
  // What the robot as a whole would refuse, from the manifests (rcand/sdk/contract/plan.hpp): every driver's settings
  // that fail its schema, a pin, channel, address or servo id two settings claim, a config block a capability reads
  // (camera) that fails its schema, a need under a config condition nothing started offers (camera.depth without
  // vision). --check-config reports these, and a start refuses with them before any instance exists.
  std::vector<yaml::ConfigDiagnostic> plan_problems(const config::RobotConfig& config,
                                                    const std::vector<std::string>& capabilities);

  CapabilityInstance* capability(std::string_view name) noexcept;
  const std::deque<DriverInstance>& drivers() const noexcept { return drivers_; }
  const std::deque<CapabilityInstance>& capabilities() const noexcept { return capabilities_; }

  // Any thread: an instance's status(), through the status reader (a hang fails the instance instead of holding
  // the caller). nullopt without an object, after a throw, or once it hung.
  std::optional<nlohmann::json> status_of(const DriverInstance& instance) { return status_at(instance.status_index); }
  std::optional<nlohmann::json> status_of(const CapabilityInstance& instance) { return status_at(instance.status_index); }
  // Every started, healthy capability's status(), read in parallel; one entry per capabilities() element.
  std::vector<std::optional<nlohmann::json>> capability_statuses();

  // The stop path, after the halt: starts every capability's on_estop(), in parallel on the estop crew, and returns
  // without waiting (the answer waits for the halts only; a job can move nothing once the latch is set, the gate
  // refuses it). The crew's watcher logs an on_estop() still running at kEstopNotifyDeadline and one that threw (its
  // capability is then marked failed).
  void notify_estop() noexcept;
  static constexpr std::chrono::milliseconds kEstopNotifyDeadline{50};
  // Main thread, once: capabilities shut down (in parallel) and their workers joined, then drivers likewise. A
  // shutdown() that throws is logged; one still running after kShutdownDeadline is logged and left running (its
  // objects are never destroyed), so a stuck plugin cannot keep rcand from exiting.
  void shutdown() noexcept;
  static constexpr std::chrono::milliseconds kShutdownDeadline{2000};

  // A development reload of plugin `id` (docs/protocol.md §7.15), after the kernel latched the e-stop: its capability
  // instances are held closed (503) and drained; its drivers taken out of the actuator table (ActuatorTable::retire:
  // halts and the gate skip them) once no call uses them; all of them shut down and destroyed; the plugin re-read
  // and re-opened from disk (PluginHost::reopen); its instances started again, each driver back in its slot. When a
  // call into the old code does not return, nothing is destroyed and the instances stay failed (restart rcand). Not
  // concurrently with itself or shutdown() (the kernel serializes).
  // `halt_first` runs once the request is known to be valid, before anything of the plugin stops.
  ReloadResult reload(const std::string& id, const config::RobotConfig& config, const std::function<void()>& halt_first);

 private:
  std::optional<nlohmann::json> status_at(const std::size_t& status_index);
  // The on_estop() crew and the status reader over every instance with an object, except those of plugin `skip`;
  // returns the ones they replace (still running what they were asked).
  std::pair<std::shared_ptr<DeadlineCrew>, std::shared_ptr<StatusReader>> start_crews(std::string_view skip = {});
  void start_capability(CapabilityInstance& instance, const config::RobotConfig& config);
  const RegisteredCapability* prepare_capability(CapabilityInstance& instance, const config::RobotConfig& config);
  void launch_capability(CapabilityInstance& instance, const RegisteredCapability& registered, const config::RobotConfig& config);
  // Creates and starts `instance` for config.drivers[index]; its actuator goes in the table at startup, or back in
  // its slot after a reload (one that became an actuator, or changed interface, fails: the table is fixed).
  void start_driver(DriverInstance& instance, std::size_t index, const config::RobotConfig& config);
  // The indices in drivers_ of the driver instances plugin `id` serves, or would serve (it failed before it could).
  std::vector<std::size_t> drivers_of(const std::string& id);
  // `members` out of the actuator table, shut down and destroyed; false when a call into one of them did not return
  // (they are then back in their slots, never destroyed).
  bool stop_drivers(const std::vector<DriverInstance*>& members);
  // The reload's instances started again from the reopened plugin, or marked failed when their old version could not
  // be stopped; then the crews rebuilt over every instance.
  void restart_after_reload(const std::vector<std::size_t>& driver_indices, const std::vector<CapabilityInstance*>& members,
                            bool capabilities_stopped, bool stopped, const config::RobotConfig& config);
  // The capability instances plugin `id` serves, or would serve (it failed before it could).
  std::vector<CapabilityInstance*> instances_of(const std::string& id);
  // `members` (of plugin `id`) held closed, drained, out of the crews, shut down and destroyed; false when one of
  // them could not be stopped (its objects are then left alive, never destroyed under a running call).
  bool stop_capabilities(const std::vector<CapabilityInstance*>& members, const std::string& id, std::chrono::milliseconds drain);
  // The first interface the plugin's manifest `requires` that no configured driver implements (a driver that failed
  // counts: the capability starts, and its state follows that driver's).
  std::optional<std::string> missing_requirement(const PluginRecord& plugin) const;
  void report_estop_round(const std::vector<DeadlineCrew::Outcome>& outcomes);

  PluginHost& host_;
  KernelServices& services_;
  ActuatorTable& actuators_;
  std::deque<DriverInstance> drivers_;
  std::deque<CapabilityInstance> capabilities_;
  bool shut_down_ = false;
  bool drivers_started_ = false;  // from here on the actuator table is fixed
  // A capability's on_estop() (or any status()) still running at shutdown: objects are leaked rather than
  // destroyed under it.
  bool abandon_capabilities_ = false;
  bool abandon_drivers_ = false;
  std::shared_ptr<CallWaiter> start_waiter_ = std::make_shared<CallWaiter>();  // capabilities' starts wait on it
  // Replaced by a reload while other threads use them: read and swapped under crews_mutex_ (which also guards every
  // instance's status_index).
  mutable std::mutex crews_mutex_;
  std::shared_ptr<DeadlineCrew> estop_crew_;     // declared after the instances: stopped before they are destroyed
  std::shared_ptr<StatusReader> status_reader_;  // likewise
};

}  // namespace rcand::kernel
