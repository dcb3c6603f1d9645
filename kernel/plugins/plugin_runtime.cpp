#include "kernel/plugins/plugin_runtime.hpp"
#include "kernel/registry/standard_capabilities.hpp"

#include <mutex>
#include <set>

#include "kernel/plugins/guarded.hpp"
#include "libs/base/bounded_call.hpp"
#include "libs/base/bounded_text.hpp"
#include "libs/base/closest_match.hpp"
#include "libs/base/keep_forever.hpp"
#include "libs/base/stop_path_priority.hpp"
#include "libs/config/config_access.hpp"
#include "libs/config/plugin_settings.hpp"
#include "libs/isolation/host_process.hpp"
#include "libs/isolation/isolated_capability.hpp"
#include "rcand/sdk/contract/plan.hpp"

namespace rcand::kernel {
namespace {

// The instance's settings against its manifest's schema for that item (`kind` "driver" or "capability", `name` its
// protocol or name); a fault is a config error at the key's file:line:column.
nlohmann::json validated_settings(const config::RobotConfig& config, const PluginRecord& plugin, std::string_view kind,
                                  const std::string& name, const nlohmann::json& settings, const std::string& path,
                                  std::vector<sdk::contract::Claim>* claims = nullptr) {
  const nlohmann::json schema = plugin.manifest ? settings_schema_of(*plugin.manifest, kind, name) : nlohmann::json::object();
  return config::plugin_settings(config, plugin.id, schema, settings, kind == "driver", path, claims);
}

// What `plugin`'s manifest provides as `kind` `name`, for the plan rule.
sdk::contract::PlannedItem planned_item(const PluginRecord& plugin, const std::string& kind, const std::string& name) {
  if (plugin.manifest)
    for (const auto& item : plugin.manifest->provides)
      if (item.kind == kind && item.name == name) return {kind, name, plugin.id, item.entry};
  return {kind, name, plugin.id, nlohmann::json::object()};
}

const std::string& key_of(const RegisteredDriver& item) { return item.info.protocol; }
const std::string& key_of(const RegisteredCapability& item) { return item.info.name; }

// The registration for `key` (a driver protocol or capability name) in the first loaded plugin that provides it.
template <class Registered>
std::pair<const Registered*, PluginRecord*> find_loaded(PluginHost& host, const std::vector<const PluginRecord*>& providers,
                                                        std::vector<Registered> PluginRecord::*list, std::string_view key) {
  PluginRecord* last = nullptr;
  for (const auto* candidate : providers) {
    last = host.find(candidate->id);
    if (last == nullptr || last->state != PluginState::Loaded) continue;
    for (const auto& item : last->*list)
      if (key_of(item) == key) return {&item, last};
  }
  return {nullptr, last};
}

// Plugins built before ABI 1.2 cannot offer services: a started driver or capability implementing
// sdk::ObstacleSource (vision's depth zones) is offered for them, unless it offered itself. The first one wins; a
// later one is refused and logged by the directory.
template <class Object> void offer_obstacle_source(InstanceContext& context, const Object* object) {
  const auto* source = dynamic_cast<const sdk::ObstacleSource*>(object);
  if (source != nullptr && sdk::find<sdk::ObstacleSource>(context) != source) sdk::offer<sdk::ObstacleSource>(context, *source);
}

template <class T> void never_destroy(std::shared_ptr<T> shared) {
  if (!shared) return;
  auto holder = std::make_unique<std::shared_ptr<T>>(std::move(shared));
  keep_forever(holder);
}

// Crews start_crews() replaced: false, and never destroyed, when a call into plugin code still runs on them.
bool retire_crews(std::pair<std::shared_ptr<DeadlineCrew>, std::shared_ptr<StatusReader>> old) {
  auto& [crew, reader] = old;
  if ((!crew || crew->quiesce(std::chrono::milliseconds(500))) && (!reader || reader->quiesce(std::chrono::milliseconds(250))))
    return true;
  never_destroy(std::move(crew));
  never_destroy(std::move(reader));
  return false;
}

// The plugin's factory, then start(), then `more` (a capability's routes()), all through the trampoline, on a thread
// of their own, waited for up to `timeout`: a plugin that hangs at startup fails its instance instead of keeping the
// robot from ever serving. The object is kept when only start() failed (the instance is marked failed, and
// shutdown() still reaches it); nullptr when there is nothing to keep. `abandoned` is set when the thread did not
// return in time: it may still run plugin code with `context`, which the caller must then never destroy.
template <class Object>
std::unique_ptr<Object> create_and_start(const std::string& who,
                                         const std::function<std::unique_ptr<Object>(sdk::PluginContext&)>& factory,
                                         InstanceContext& context, InstanceHealth& health, std::chrono::milliseconds timeout,
                                         bool& abandoned, std::function<void(Object&)> more = {},
                                         std::shared_ptr<CallWaiter> waiter = std::make_shared<CallWaiter>()) {
  struct Startup {
    std::mutex mutex;
    bool abandoned = false;
    std::unique_ptr<Object> object;
    Fault failure;  // no reason: everything returned normally
  };
  auto startup = std::make_shared<Startup>();
  const bool finished = bounded_call(
      "plugin.start", timeout,
      // The factory copied: a thread given up on still calls it after this returns, and the caller's may be a temporary.
      [startup, who, factory, &context, more = std::move(more)] {
        Fault failure;
        std::unique_ptr<Object> made;
        if (auto object = guarded_result(who, "factory", failure, [&] { return factory(context); }); object && *object) {
          made = std::move(*object);
          if (guarded_call(who, "start", failure, [&] { made->start(); }) && more)
            guarded_call(who, "routes", failure, [&] { more(*made); });
        } else if (failure.reason.empty()) {
          failure.reason = "factory returned nothing";
        }
        std::lock_guard lock(startup->mutex);
        if (startup->abandoned) {
          keep_forever(made);  // too late: the kernel gave up on it; never destroyed, like its context
          return;
        }
        startup->object = std::move(made);
        startup->failure = std::move(failure);
      },
      waiter);

  std::lock_guard lock(startup->mutex);
  if (!finished) {
    startup->abandoned = abandoned = true;
    keep_forever(startup->object);  // finished right after the timeout: given up on all the same, never destroyed
    health.mark_failed(waiter->given_up ? "rcand shut down before it finished starting"
                                        : "did not finish starting within " + std::to_string(timeout.count()) +
                                              " ms (runtime.plugin_start_timeout_ms)");
    logger("kernel.plugins")->error("{}: {}", who, health.reason());
    return nullptr;
  }
  if (!startup->failure.reason.empty()) health.mark_failed(std::move(startup->failure));
  return std::move(startup->object);
}

// What makes a plugin's route list unusable (it would fail every request, or shadow another route), if anything.
template <class RouteType> std::optional<std::string> route_problem(const std::vector<RouteType>& routes) {
  static const std::set<std::string> kMethods{"GET", "POST", "PUT", "PATCH", "DELETE", "HEAD"};
  std::set<std::pair<std::string, std::string>> seen;
  for (const auto& route : routes) {
    const std::string name = "'" + route.method + " " + route.path + "'";
    if (!kMethods.contains(route.method)) return name + ": method must be one of GET, POST, PUT, PATCH, DELETE, HEAD";
    if (!route.path.empty() && route.path.front() != '/') return name + ": path must be empty or start with '/'";
    if (!route.handler) return name + ": no handler";
    std::string key = route.path;
    if constexpr (requires { route.action_type; }) key += "\n" + route.action_type;
    if (!seen.insert({route.method, key}).second) return name + ": declared twice";
  }
  return std::nullopt;
}

// `registered`'s factory, or for a capability configured `isolation: process` (rcand/sdk/contract/isolation.hpp) one
// that runs it in rcand-plugin-host; its deaths are audited, a crash loop fails the instance.
sdk::CapabilityFactory factory_of(const RegisteredCapability& registered, const PluginRecord& plugin,
                                  CapabilityInstance& instance, KernelServices& services, const config::RobotConfig& config) {
  const ProvidedItem* item = plugin.manifest ? find_provided(*plugin.manifest, "capability", instance.name) : nullptr;
  const auto isolation = sdk::contract::isolation_of(item != nullptr ? item->entry : nlohmann::json(),
                                                     config.runtime.capabilities.value(instance.name, nlohmann::json()));
  if (!isolation.process) return registered.factory;
  const auto under = [](int ms) { return std::chrono::milliseconds(std::max(100, ms - 250)); };
  const auto binary = isolation::find_host_binary(RCAND_PLUGIN_HOST_DIR);
  const auto private_files = config::private_files(config);
  isolation::HostSpec spec{.binary = binary.value_or(""),
                           .plugin_paths = {plugin.manifest_file.parent_path().string()},
                           .plugin_id = plugin.id,
                           .isolation = isolation,
                           .hidden = {private_files.begin(), private_files.end()},
                           .request_timeout = under(config.runtime.handler_timeout_ms),
                           .start_timeout = under(config.runtime.plugin_start_timeout_ms)};
  isolation::HostEvents events{[&services, id = plugin.id](const std::string& event, const std::string& detail) {
                                 if (services.audit == nullptr) return;
                                 AuditEntry entry;
                                 entry.principal = "plugin:" + id, entry.ruri = services.ruri, entry.event = event;
                                 entry.outcome = "error", entry.detail = detail;
                                 services.audit->record(std::move(entry));
                               },
                               [&health = instance.health](const std::string& reason) { health.mark_failed(reason); }};
  return [spec, events](sdk::PluginContext& context) -> std::unique_ptr<sdk::Capability> {
    if (spec.binary.empty())
      throw std::runtime_error(
          "configured isolation: process, and rcand-plugin-host is not installed beside rcand or in " RCAND_PLUGIN_HOST_DIR);
    return std::make_unique<isolation::IsolatedCapability>(context, spec, events);
  };
}

}  // namespace

PluginRuntime::PluginRuntime(PluginHost& host, KernelServices& services, ActuatorTable& actuators)
    : host_(host), services_(services), actuators_(actuators) {}

PluginRuntime::~PluginRuntime() {
  shutdown();
  estop_crew_.reset();
  if (status_reader_ && !status_reader_->quiesce(std::chrono::milliseconds(100)))
    abandon_capabilities_ = abandon_drivers_ = true;  // a status() hangs: which object it reads is not known
  status_reader_.reset();
  auto abandon = [](auto& instances) {
    for (auto& instance : instances) {
      keep_forever(instance.object);
      keep_forever(instance.context);
    }
  };
  if (abandon_capabilities_) abandon(capabilities_);
  if (abandon_drivers_) abandon(drivers_);
}

void PluginRuntime::start_drivers(const config::RobotConfig& config) {
  for (std::size_t i = 0; i < config.drivers.size(); ++i) {
    auto& instance = drivers_.emplace_back();
    instance.id = config.drivers[i].id;
    instance.protocol = config.drivers[i].protocol;
    start_driver(instance, i, config);
  }
  drivers_started_ = true;
}

void PluginRuntime::start_driver(DriverInstance& instance, std::size_t index, const config::RobotConfig& config) {
  auto log = logger("kernel.plugins");
  const auto& entry = config.drivers[index];

  auto [registered, plugin] =
      find_loaded(host_, host_.providers_of_driver(entry.protocol), &PluginRecord::drivers, entry.protocol);
  if (registered == nullptr) {
    if (plugin != nullptr && plugin->manifest)  // what it would have been: a capability that needs it follows it
      for (const auto& item : plugin->manifest->provides)
        if (item.kind == "driver" && item.name == entry.protocol && item.actuates) instance.interface = item.interface;
    instance.health.mark_failed(plugin == nullptr ? "no installed plugin provides driver protocol '" + entry.protocol + "'"
                                                  : "plugin " + plugin->id + " is " + std::string(to_string(plugin->state)) +
                                                        ": " + plugin->reason);
    log->error("driver {}: {}", entry.id, instance.health.reason());
    return;
  }
  instance.plugin_id = plugin->id;
  instance.actuates = registered->info.actuates;
  if (instance.actuates) instance.interface = registered->info.interface;
  auto settings =
      validated_settings(config, *plugin, "driver", entry.protocol, entry.settings, "drivers[" + std::to_string(index) + "]");
  instance.context = std::make_unique<InstanceContext>(plugin->id, entry.id, services_, std::move(settings), instance.health);

  instance.who = "plugin " + plugin->id + " driver " + entry.id;
  bool abandoned = false;
  instance.object = create_and_start(instance.who, registered->factory, *instance.context, instance.health,
                                     std::chrono::milliseconds(config.runtime.plugin_start_timeout_ms), abandoned);
  if (abandoned) keep_forever(instance.context);  // still in use by the plugin thread that never returned
  if (!instance.object) return;

  if (instance.actuates) {
    std::string refused;  // why it cannot serve its actuator
    auto* actuator = dynamic_cast<sdk::ActuatorDriver*>(instance.object.get());
    ActuatorSlot* slot = actuators_.find(entry.id);
    if (actuator == nullptr) refused = "registered as actuating but is not an ActuatorDriver";
    else if (slot == nullptr && drivers_started_)  // a reload: the stop path reads the table without locks
      refused = "became an actuator in a reload; restart rcand to put it in the actuator table";
    else if (slot == nullptr)
      actuators_.add(entry.id, std::string(actuator->interface_name()), plugin->id, actuator, &instance.health);
    else if (slot->interface != actuator->interface_name())
      refused = "its interface changed from " + slot->interface + " to " + std::string(actuator->interface_name()) +
                " in a reload; restart rcand";
    else ActuatorTable::install(*slot, actuator);
    if (!refused.empty()) {
      instance.health.mark_failed(refused);
      log->error("driver {}: {}", entry.id, refused);
      return;
    }
  }
  if (!instance.health.failed()) offer_obstacle_source(*instance.context, instance.object.get());
  log->info("driver {} ({}, {}) {}", entry.id, entry.protocol, plugin->id,
            instance.health.failed() ? "failed: " + instance.health.reason() : "started");
}

void PluginRuntime::declare_capabilities(const std::vector<std::string>& names, const config::RobotConfig& config) {
  for (const auto& name : names) {
    if (name == kStatusCapability) continue;  // the kernel's own
    auto& instance = capabilities_.emplace_back();
    instance.name = name;
    instance.registered = prepare_capability(instance, config);
    instance.starting = instance.registered != nullptr;
  }
  start_crews();  // the drivers' status readers, and an on_estop() crew from the start
}

void PluginRuntime::start_declared(const config::RobotConfig& config, const std::function<bool()>& go_on,
                                   const std::function<void(CapabilityInstance&)>& up) {
  for (auto& instance : capabilities_) {
    if (!instance.starting.load()) continue;
    if (go_on()) {
      launch_capability(instance, *instance.registered, config);
      retire_crews(start_crews());  // its on_estop() and status() from now on
    } else {
      instance.health.mark_failed("rcand shut down before it started");
    }
    instance.starting.store(false);  // after its fields: a request that sees it up reads them whole
    if (up) up(instance);
  }
}

void PluginRuntime::start_capability(CapabilityInstance& instance, const config::RobotConfig& config) {
  if (const RegisteredCapability* registered = prepare_capability(instance, config))
    launch_capability(instance, *registered, config);
}

// Its plugin found, its requirements and settings checked (a ConfigError throws), its context and worker made: no
// plugin code runs. Null when it failed (named in its health).
const RegisteredCapability* PluginRuntime::prepare_capability(CapabilityInstance& instance, const config::RobotConfig& config) {
  auto log = logger("kernel.plugins");
  const std::string& name = instance.name;
  auto [registered, plugin] = find_loaded(host_, host_.providers_of_capability(name), &PluginRecord::capabilities, name);
  if (registered == nullptr) {
    instance.health.mark_failed(plugin == nullptr ? "no installed plugin provides it"
                                                  : "plugin " + plugin->id + " is " + std::string(to_string(plugin->state)) +
                                                        ": " + plugin->reason);
    log->error("capability {}: {}", name, instance.health.reason());
    return nullptr;
  }
  instance.plugin_id = plugin->id;
  instance.actuates = registered->info.actuates;
  if (plugin->manifest) instance.needs = plugin->manifest->requires_;
  if (const auto missing = missing_requirement(*plugin)) {
    instance.health.mark_failed("requires a " + *missing + " actuator, and no configured driver provides one");
    log->error("capability {}: {}", name, instance.health.reason());
    return nullptr;
  }
  const nlohmann::json raw =
      config.runtime.capabilities.contains(name) ? config.runtime.capabilities.at(name) : nlohmann::json::object();
  auto settings = validated_settings(config, *plugin, "capability", name, raw, "runtime.capabilities." + name);
  instance.context = std::make_unique<InstanceContext>(plugin->id, name, services_, std::move(settings), instance.health);
  instance.handler_worker = std::make_unique<WorkerThread>(
      "cap." + name, [&health = instance.health](const std::string& why) { health.mark_failed(why); });
  instance.who = "plugin " + plugin->id + " capability " + name;
  return registered;
}

// Its factory, start() and routes(), bounded by runtime.plugin_start_timeout_ms.
void PluginRuntime::launch_capability(CapabilityInstance& instance, const RegisteredCapability& registered,
                                      const config::RobotConfig& config) {
  const PluginRecord* plugin = host_.find(instance.plugin_id);
  bool abandoned = false;
  // Shared with the plugin thread: one that was given up on may still write them after this returns.
  auto routes = std::make_shared<std::pair<std::vector<sdk::Route>, std::vector<sdk::StreamRoute>>>();
  instance.object = create_and_start<sdk::Capability>(
      instance.who, factory_of(registered, *plugin, instance, services_, config), *instance.context, instance.health,
      std::chrono::milliseconds(config.runtime.plugin_start_timeout_ms), abandoned,
      [routes, minor = plugin->abi_minor](sdk::Capability& object) {
        routes->first = object.routes();
        if (minor >= 2) routes->second = object.stream_routes();  // older: no such virtual
      },
      start_waiter_);
  if (abandoned) keep_forever(instance.context);  // still in use by the plugin thread that never returned
  if (!instance.object) return;
  if (!instance.health.failed()) {
    if (auto problem = route_problem(routes->first))
      instance.health.mark_failed("routes() returned an unusable route: " + *problem);
    else if (auto bad = route_problem(routes->second))
      instance.health.mark_failed("stream_routes() returned an unusable route: " + *bad);
    else {
      instance.routes = std::move(routes->first);
      instance.stream_routes = std::move(routes->second);
    }
  }
  if (!instance.health.failed()) offer_obstacle_source(*instance.context, instance.object.get());
  logger("kernel.plugins")
      ->info("capability {} ({}) {}, {} routes", instance.name, plugin->id,
             instance.health.failed() ? "failed: " + instance.health.reason() : "started",
             instance.routes.size() + instance.stream_routes.size());
}

std::optional<nlohmann::json> PluginRuntime::status_at(const std::size_t& status_index) {
  std::shared_ptr<StatusReader> reader;
  std::size_t index = kNoStatus;
  {
    std::lock_guard lock(crews_mutex_);
    reader = status_reader_;
    index = status_index;
  }
  if (!reader || index == kNoStatus) return std::nullopt;
  return reader->read(index);
}

std::vector<std::optional<nlohmann::json>> PluginRuntime::capability_statuses() {
  std::vector<std::size_t> indices;
  std::shared_ptr<StatusReader> reader;
  {
    std::lock_guard lock(crews_mutex_);
    for (const auto& instance : capabilities_) indices.push_back(instance.health.failed() ? kNoStatus : instance.status_index);
    reader = status_reader_;
  }
  if (!reader) return std::vector<std::optional<nlohmann::json>>(indices.size());
  return reader->read(indices);
}

namespace {

// "no installed plugin provides driver protocol 'x'; did you mean 'y'?", or why the plugin that would is not loaded.
std::string unserved(const PluginHost& host, std::string_view kind, const std::string& name, const PluginRecord* plugin) {
  if (plugin != nullptr)
    return "plugin " + plugin->id + " (" + std::string(kind) + " '" + name + "') is " + std::string(to_string(plugin->state)) +
           ": " + plugin->reason;
  std::vector<std::string> known;
  for (const auto& record : host.records())
    if (record->manifest)
      for (const auto& item : record->manifest->provides)
        if ((kind == "driver protocol") == (item.kind == "driver")) known.push_back(item.name);
  std::string message = "no installed plugin provides " + std::string(kind) + " '" + name + "'";
  if (const auto guess = closest_match(name, known)) message += "; did you mean '" + *guess + "'?";
  return message;
}

}  // namespace

std::vector<yaml::ConfigDiagnostic> PluginRuntime::check(const config::RobotConfig& config,
                                                         const std::vector<std::string>& capabilities) {
  std::vector<yaml::ConfigDiagnostic> problems;
  const auto problem = [&](const std::string& path, std::string message) {
    problems.push_back({yaml::ConfigDiagnostic::Severity::Error, config.mark_of(path), path, std::move(message)});
  };
  const auto settings = [&](const PluginRecord& plugin, const char* kind, const std::string& name, const nlohmann::json& value,
                            const std::string& path) {
    try {
      validated_settings(config, plugin, kind, name, value, path);
    } catch (const yaml::ConfigError& e) {
      problems.insert(problems.end(), e.diagnostics().begin(), e.diagnostics().end());
    }
  };
  std::set<std::string> interfaces;  // what the configured actuating drivers provide
  bool driver_unserved = false;      // then a capability's missing actuator is that driver: said once, by its error
  for (std::size_t i = 0; i < config.drivers.size(); ++i) {
    const auto& entry = config.drivers[i];
    const std::string path = "drivers[" + std::to_string(i) + "]";
    auto [registered, plugin] =
        find_loaded(host_, host_.providers_of_driver(entry.protocol), &PluginRecord::drivers, entry.protocol);
    if (registered == nullptr) {
      problem(path + ".protocol", unserved(host_, "driver protocol", entry.protocol, plugin));
      driver_unserved = true;
      continue;
    }
    if (registered->info.actuates) interfaces.insert(registered->info.interface);  // its settings: plan_problems()
  }
  for (const auto& name : capabilities) {
    if (name == kStatusCapability) continue;  // the kernel's own
    auto [registered, plugin] = find_loaded(host_, host_.providers_of_capability(name), &PluginRecord::capabilities, name);
    if (registered == nullptr) {
      problem("rcan_protocol.capabilities", unserved(host_, "capability", name, plugin));
      continue;
    }
    for (const auto& needed : plugin->manifest->requires_)
      if (!interfaces.contains(needed) && !driver_unserved)
        problem("rcan_protocol.capabilities",
                "capability " + name + " requires a " + needed + " actuator, and no configured driver provides one");
    const nlohmann::json raw =
        config.runtime.capabilities.contains(name) ? config.runtime.capabilities.at(name) : nlohmann::json::object();
    settings(*plugin, "capability", name, raw, "runtime.capabilities." + name);
  }
  auto plan = plan_problems(config, capabilities);
  problems.insert(problems.end(), plan.begin(), plan.end());
  return problems;
}

std::vector<yaml::ConfigDiagnostic> PluginRuntime::plan_problems(const config::RobotConfig& config,
                                                                 const std::vector<std::string>& capabilities) {
  std::vector<yaml::ConfigDiagnostic> problems;
  const auto add = [&](const std::string& path, std::string message) {
    problems.push_back({yaml::ConfigDiagnostic::Severity::Error, config.mark_of(path), path, std::move(message)});
  };
  std::vector<sdk::contract::InstanceClaims> claims;
  std::vector<sdk::contract::PlannedItem> planned, installed;
  for (std::size_t i = 0; i < config.drivers.size(); ++i) {
    const auto& entry = config.drivers[i];
    auto [registered, plugin] =
        find_loaded(host_, host_.providers_of_driver(entry.protocol), &PluginRecord::drivers, entry.protocol);
    if (registered == nullptr) continue;  // check() and the start name it
    planned.push_back(planned_item(*plugin, "driver", entry.protocol));
    auto& instance =
        claims.emplace_back(sdk::contract::InstanceClaims{"drivers[" + std::to_string(i) + "]", "driver " + entry.id, {}});
    try {
      validated_settings(config, *plugin, "driver", entry.protocol, entry.settings, instance.where, &instance.claims);
    } catch (const yaml::ConfigError& e) {
      problems.insert(problems.end(), e.diagnostics().begin(), e.diagnostics().end());
    }
  }
  for (const auto& name : capabilities) {
    auto [registered, plugin] = find_loaded(host_, host_.providers_of_capability(name), &PluginRecord::capabilities, name);
    if (registered == nullptr) continue;
    planned.push_back(planned_item(*plugin, "capability", name));
    const auto reads = planned.back().item.value("reads", nlohmann::json::object());
    for (const auto& [block, schema] : reads.items())
      if (config.doc.contains(block)) try {
          config::plugin_settings(config, plugin->id, schema, config.doc[block], false, block);
        } catch (const yaml::ConfigError& e) {
          problems.insert(problems.end(), e.diagnostics().begin(), e.diagnostics().end());
        }
  }
  for (const auto& conflict : sdk::contract::claim_conflicts(claims))
    add(claims[conflict.instance].where + "." + conflict.key, conflict.problem);
  for (const auto& record : host_.records())
    if (record->manifest)
      for (const auto& item : record->manifest->provides) installed.push_back({item.kind, item.name, record->id, item.entry});
  for (const auto& [key, problem] : sdk::contract::unmet_needs(planned, installed, config.doc)) add(key, problem);
  return problems;
}

std::optional<std::string> PluginRuntime::missing_requirement(const PluginRecord& plugin) const {
  if (!plugin.manifest) return std::nullopt;
  for (const auto& interface : plugin.manifest->requires_) {
    bool provided = false;
    for (const auto& driver : drivers_) provided = provided || driver.interface == interface;
    if (!provided) return interface;
  }
  return std::nullopt;
}

CapabilityInstance* PluginRuntime::capability(std::string_view name) noexcept {
  for (auto& instance : capabilities_)
    if (instance.name == name) return &instance;
  return nullptr;
}

void PluginRuntime::notify_estop() noexcept {
  std::shared_ptr<DeadlineCrew> crew;
  {
    std::lock_guard lock(crews_mutex_);
    crew = estop_crew_;
  }
  if (crew) return crew->start_all();  // reported by the crew's watcher (start_crews)
  for (auto& instance : capabilities_)
    if (instance.object) instance.object->on_estop();
}

// The estop crew's watcher, off the stop path: an on_estop() that threw marks its capability failed, one still
// running at kEstopNotifyDeadline is logged.
void PluginRuntime::report_estop_round(const std::vector<DeadlineCrew::Outcome>& outcomes) {
  for (const auto& outcome : outcomes) {
    if (outcome.state == DeadlineCrew::State::Done) continue;
    const std::string why = outcome.state == DeadlineCrew::State::Failed
                                ? "on_estop() threw: " + outcome.error
                                : "on_estop() did not return within " + std::to_string(kEstopNotifyDeadline.count()) + " ms";
    logger("kernel.plugins")->error("capability {}: {}", outcome.name, why);
    if (auto* instance = capability(outcome.name); instance != nullptr && outcome.state == DeadlineCrew::State::Failed)
      instance->health.mark_failed(why);
  }
}

namespace {

// Every instance's shutdown() in parallel on a crew of its own, waited for up to `deadline`, after their service
// offers were withdrawn; then the workers of each instance whose hook returned are joined. A hook that throws out
// of its noexcept is contained and logged; one still running at the deadline is logged and left running, and true
// is returned: its object and context must never be destroyed.
template <class Instance>
bool shut_down_all(const std::vector<Instance*>& instances, std::chrono::milliseconds deadline) noexcept {
  for (auto* instance : instances)
    if (instance->context) instance->context->withdraw_offers();
  std::vector<Instance*> members;
  std::optional<DeadlineCrew> crew;
  try {
    std::vector<DeadlineCrew::Job> jobs;
    for (auto* instance : instances) {
      if (!instance->object) continue;
      jobs.push_back({instance->who, [object = instance->object.get()] { object->shutdown(); }});
      members.push_back(instance);
    }
    crew.emplace("shutdown", std::move(jobs));
  } catch (...) {  // no memory or no threads for the crew: shut down inline, as a last resort
    for (auto* instance : instances)
      if (instance->object) instance->object->shutdown();
    return false;
  }
  const auto outcomes = crew->run_all(std::chrono::steady_clock::now() + deadline);
  bool abandoned = false;
  for (std::size_t i = 0; i < members.size(); ++i) {
    const auto state = i < outcomes.size() ? outcomes[i].state : DeadlineCrew::State::Pending;
    try {
      if (state == DeadlineCrew::State::Failed)
        logger("kernel.plugins")->error("{}: shutdown() threw: {}", members[i]->who, outcomes[i].error);
      if (state == DeadlineCrew::State::Pending)
        logger("kernel.plugins")
            ->error("{}: shutdown() did not return within {} ms; left running", members[i]->who, deadline.count());
    } catch (...) {
    }
    if (state == DeadlineCrew::State::Pending) abandoned = true;
    else if (members[i]->context) members[i]->context->join_workers();
  }
  return abandoned;
}

template <class Instances> auto pointers_to(Instances& instances) {
  std::vector<typename Instances::value_type*> out;
  for (auto& instance : instances) out.push_back(&instance);
  return out;
}

}  // namespace

void PluginRuntime::shutdown() noexcept {
  if (shut_down_) return;
  shut_down_ = true;
  if (estop_crew_ && !estop_crew_->quiesce(std::chrono::milliseconds(500))) abandon_capabilities_ = true;
  for (auto& instance : capabilities_)
    if (instance.handler_worker) instance.handler_worker->join();
  try {
    if (shut_down_all(pointers_to(capabilities_), kShutdownDeadline)) abandon_capabilities_ = true;
    if (shut_down_all(pointers_to(drivers_), kShutdownDeadline)) abandon_drivers_ = true;
  } catch (...) {  // no memory for the lists: leave the objects to the process's end
    abandon_capabilities_ = abandon_drivers_ = true;
  }
}

// The threads every started instance gets from the kernel: an on_estop() caller each (the stop path's notify crew)
// and a status() reader each.
std::pair<std::shared_ptr<DeadlineCrew>, std::shared_ptr<StatusReader>> PluginRuntime::start_crews(std::string_view skip) {
  const auto wanted = [skip](const auto& instance) { return instance.object && (skip.empty() || instance.plugin_id != skip); };
  std::vector<DeadlineCrew::Job> jobs;
  for (auto& instance : capabilities_)
    if (wanted(instance)) jobs.push_back({instance.name, [object = instance.object.get()] { object->on_estop(); }});
  auto crew = std::make_shared<DeadlineCrew>("estop.notify", std::move(jobs), [] { enter_batch_policy(); });
  crew->watch(kEstopNotifyDeadline, [this](std::vector<DeadlineCrew::Outcome> outcomes) { report_estop_round(outcomes); });

  std::vector<StatusReader::Source> sources;
  std::vector<std::pair<std::size_t*, std::size_t>> indices;  // set with the swap, under the lock
  auto add_source = [&](auto& instance) {
    indices.emplace_back(&instance.status_index, wanted(instance) ? sources.size() : kNoStatus);
    if (!wanted(instance)) return;
    sources.push_back({instance.who, [object = instance.object.get()] { return object->status(); }, &instance.health});
  };
  for (auto& instance : drivers_) add_source(instance);
  for (auto& instance : capabilities_) add_source(instance);
  auto reader = std::make_shared<StatusReader>(std::move(sources));
  std::lock_guard lock(crews_mutex_);
  estop_crew_.swap(crew);
  status_reader_.swap(reader);
  for (auto [slot, index] : indices) *slot = index;
  return {std::move(crew), std::move(reader)};
}

std::vector<CapabilityInstance*> PluginRuntime::instances_of(const std::string& id) {
  const PluginRecord* record = host_.find(id);
  std::vector<CapabilityInstance*> out;
  for (auto& instance : capabilities_) {
    const bool would_serve =
        instance.plugin_id.empty() && record != nullptr && record->manifest &&
        std::any_of(record->manifest->provides.begin(), record->manifest->provides.end(),
                    [&](const ProvidedItem& item) { return item.kind == "capability" && item.name == instance.name; });
    if (instance.plugin_id == id || would_serve) out.push_back(&instance);
  }
  return out;
}

bool PluginRuntime::stop_capabilities(const std::vector<CapabilityInstance*>& members, const std::string& id,
                                      std::chrono::milliseconds drain) {
  bool drained = true;
  for (auto* instance : members) drained = instance->gate->close_and_drain(drain) && drained;  // in-flight calls finish
  const bool crews_quiet = retire_crews(start_crews(id));  // no on_estop() or status() reaches them from here on
  if (drained)
    for (auto* instance : members)
      if (instance->handler_worker) instance->handler_worker->join();
  const bool stopped = drained && crews_quiet && !shut_down_all(members, kShutdownDeadline);
  for (auto* instance : members) {
    if (!stopped) {  // a call still runs in the old code: its objects stay alive, out of service
      keep_forever(instance->object);
      keep_forever(instance->context);
      keep_forever(instance->handler_worker);
    }
    instance->object.reset();
    instance->handler_worker.reset();
    instance->context.reset();
    instance->routes.clear();
    instance->stream_routes.clear();
  }
  return stopped;
}

std::vector<std::size_t> PluginRuntime::drivers_of(const std::string& id) {
  const PluginRecord* record = host_.find(id);
  std::vector<std::size_t> out;
  for (std::size_t i = 0; i < drivers_.size(); ++i) {
    const auto& driver = drivers_[i];
    const auto providers =
        driver.plugin_id.empty() ? host_.providers_of_driver(driver.protocol) : std::vector<const PluginRecord*>{};
    const bool would_serve = !providers.empty() && providers.front() == record;  // it failed before it could
    if (driver.plugin_id == id || would_serve) out.push_back(i);
  }
  return out;
}

bool PluginRuntime::stop_drivers(const std::vector<DriverInstance*>& members) {
  const auto deadline = std::chrono::steady_clock::now() + kShutdownDeadline;
  std::vector<std::pair<ActuatorSlot*, sdk::ActuatorDriver*>> retired;
  bool idle = true;
  for (auto* instance : members) {
    ActuatorSlot* slot = instance->object && instance->actuates ? actuators_.find(instance->id) : nullptr;
    if (slot == nullptr) continue;
    retired.emplace_back(slot, slot->driver.load());
    idle = ActuatorTable::retire(*slot, deadline) && idle;
  }
  if (!idle) {  // a call into the old code did not return: every actuator keeps its driver, nothing is shut down
    for (auto [slot, driver] : retired) ActuatorTable::install(*slot, driver);
    return false;
  }
  const bool abandoned = shut_down_all(members, kShutdownDeadline);
  for (auto* instance : members) {
    if (abandoned) {  // a shutdown() still runs in the old code: its objects stay alive, out of service
      keep_forever(instance->object);
      keep_forever(instance->context);
    }
    instance->object.reset();
    instance->context.reset();
  }
  return !abandoned;
}

void PluginRuntime::restart_after_reload(const std::vector<std::size_t>& driver_indices,
                                         const std::vector<CapabilityInstance*>& members, bool capabilities_stopped, bool stopped,
                                         const config::RobotConfig& config) {
  // Each instance in service again on its new code, or failed with the reason when it could not be.
  const auto restart = [stopped](InstanceHealth& health, const auto& start) {
    health.reset();
    if (!stopped) return health.mark_failed("plugin reload: a call into the old version did not finish; restart rcand");
    try {
      start();
    } catch (const std::exception& e) {  // the new manifest's settings schema refuses the config
      health.mark_failed(std::string("plugin reload: ") + e.what());
    }
  };
  if (capabilities_stopped)  // else the drivers were never touched: still the old version, in service
    for (auto i : driver_indices) restart(drivers_[i].health, [&] { start_driver(drivers_[i], i, config); });
  for (auto* instance : members) restart(instance->health, [&] { start_capability(*instance, config); });
  start_crews();
}

ReloadResult PluginRuntime::reload(const std::string& id, const config::RobotConfig& config,
                                   const std::function<void()>& halt_first) {
  ReloadResult result;
  const auto refuse = [&result](int status, std::string code, std::string error) {
    result.status = status;
    result.code = std::move(code);
    result.error = std::move(error);
    return result;
  };
  const PluginRecord* record = host_.find(id);
  if (record == nullptr) return refuse(404, "NOT_FOUND", "no plugin '" + bounded_text(id) + "' is installed");
  const auto members = instances_of(id);
  const auto driver_indices = drivers_of(id);
  std::vector<DriverInstance*> drivers;
  for (auto i : driver_indices) drivers.push_back(&drivers_[i]);
  if (members.empty() && drivers.empty())
    return refuse(409, "NOT_IN_USE", "plugin " + id + " serves no driver or capability of this robot: nothing to reload");
  if (host_.reopens_left(id) <= 0)  // refused before anything stops: the robot keeps running the version it has
    return refuse(409, "RELOAD_LIMIT",
                  "plugin " + id + " was reloaded " + std::to_string(PluginHost::kMaxReopens) +
                      " times, the most one run of rcand allows (each reload keeps its old version mapped); restart rcand");

  halt_first();
  auto log = logger("kernel.plugins");
  log->warn("plugin {}: reloading ({} driver(s), {} capability instance(s))", id, drivers.size(), members.size());
  // Capabilities first (they command the drivers), then drivers: each out of the actuator table, shut down, destroyed.
  const bool capabilities_stopped = stop_capabilities(
      members, id, std::chrono::milliseconds(config.runtime.handler_timeout_ms) + std::chrono::milliseconds(500));
  const bool stopped = capabilities_stopped && stop_drivers(drivers);
  if (stopped) host_.reopen(id);
  restart_after_reload(driver_indices, members, capabilities_stopped, stopped, config);
  std::string failure;  // the first instance that does not run its new version
  const auto report = [&](const char* kind, const std::string& name, const InstanceHealth& health) {
    nlohmann::json item{{kind, name}, {"state", health.failed() ? "failed" : "running"}};
    if (health.failed()) item["reason"] = health.reason();
    if (health.failed() && failure.empty()) failure = std::string(kind) + " " + name + " failed: " + health.reason();
    result.instances.push_back(std::move(item));
  };
  for (auto* instance : drivers) report("driver", instance->id, instance->health);
  for (auto* instance : members) {
    instance->gate->open();
    report("capability", instance->name, instance->health);
  }
  std::string why;
  if (!stopped) why = "a call into its old version did not finish; restart rcand";
  else if (record->state != PluginState::Loaded)
    why = "it is " + std::string(to_string(record->state)) + (record->reason.empty() ? "" : ": " + record->reason);
  else why = failure;
  if (!why.empty())
    return refuse(500, "RELOAD_FAILED", "plugin " + id + " reload failed: " + why + " (the robot stays e-stopped)");
  log->warn("plugin {}: reloaded, version {}", id, record->version);
  return result;
}

}  // namespace rcand::kernel
