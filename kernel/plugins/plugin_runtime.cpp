#include "kernel/plugins/plugin_runtime.hpp"
#include "kernel/registry/standard_capabilities.hpp"

#include <mutex>
#include <set>

#include "kernel/plugins/bounded_call.hpp"
#include "kernel/plugins/guarded.hpp"
#include "kernel/plugins/settings_schema.hpp"
#include "libs/base/keep_forever.hpp"

namespace rcand::kernel {
namespace {

[[noreturn]] void settings_error(const RobotConfig& config, const std::string& path, const std::string& message) {
  ConfigDiagnostic diagnostic;
  diagnostic.mark = config.mark_of(path);
  diagnostic.key_path = path;
  diagnostic.message = message;
  throw ConfigError({std::move(diagnostic)});
}

nlohmann::json validated_settings(const RobotConfig& config, const PluginRecord& plugin, const nlohmann::json& settings,
                                  bool allow_unknown, const std::string& path) {
  const nlohmann::json schema = plugin.manifest ? plugin.manifest->config_schema : nlohmann::json::object();
  try {
    return apply_config_schema(schema, settings, allow_unknown);
  } catch (const ConfigSchemaError& e) {
    settings_error(config, path, std::string(e.what()) + " (settings of plugin " + plugin.id + ")");
  }
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

// The first started driver or capability implementing sdk::ObstacleSource becomes the robot's obstacle source
// (vision's depth zones), handed to every plugin through PluginContext::obstacles().
template <class Object> void offer_obstacle_source(KernelServices& services, const Object* object, const std::string& what) {
  const auto* source = dynamic_cast<const sdk::ObstacleSource*>(object);
  if (source == nullptr) return;
  const sdk::ObstacleSource* none = nullptr;
  if (services.obstacles.compare_exchange_strong(none, source)) logger("kernel.plugins")->info("{} is the obstacle source", what);
  else logger("kernel.plugins")->warn("{} also provides obstacles; the first one found is used", what);
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
                                         bool& abandoned, std::function<void(Object&)> more = {}) {
  struct Startup {
    std::mutex mutex;
    bool abandoned = false;
    std::unique_ptr<Object> object;
    std::string failure;  // empty: everything returned normally
  };
  auto startup = std::make_shared<Startup>();
  const bool finished = bounded_call("plugin.start", timeout, [startup, who, &factory, &context, more = std::move(more)] {
    std::string failure;
    std::unique_ptr<Object> made;
    if (auto object = guarded_result(who, "factory", failure, [&] { return factory(context); }); object && *object) {
      made = std::move(*object);
      if (guarded_call(who, "start", failure, [&] { made->start(); }) && more)
        guarded_call(who, "routes", failure, [&] { more(*made); });
    } else if (failure.empty()) {
      failure = "factory returned nothing";
    }
    std::lock_guard lock(startup->mutex);
    if (startup->abandoned) {
      keep_forever(made);  // too late: the kernel gave up on it; never destroyed, like its context
      return;
    }
    startup->object = std::move(made);
    startup->failure = std::move(failure);
  });

  std::lock_guard lock(startup->mutex);
  if (!finished) {
    startup->abandoned = abandoned = true;
    keep_forever(startup->object);  // finished right after the timeout: given up on all the same, never destroyed
    health.mark_failed("did not finish starting within " + std::to_string(timeout.count()) +
                       " ms (runtime.plugin_start_timeout_ms)");
    logger("kernel.plugins")->error("{}: {}", who, health.reason());
    return nullptr;
  }
  if (!startup->failure.empty()) health.mark_failed(startup->failure);
  return std::move(startup->object);
}

// What makes a plugin's route list unusable (it would fail every request, or shadow another route), if anything.
std::optional<std::string> route_problem(const std::vector<sdk::Route>& routes) {
  static const std::set<std::string> kMethods{"GET", "POST", "PUT", "PATCH", "DELETE", "HEAD"};
  std::set<std::pair<std::string, std::string>> seen;
  for (const auto& route : routes) {
    const std::string name = "'" + route.method + " " + route.path + "'";
    if (!kMethods.contains(route.method)) return name + ": method must be one of GET, POST, PUT, PATCH, DELETE, HEAD";
    if (!route.path.empty() && route.path.front() != '/') return name + ": path must be empty or start with '/'";
    if (!route.handler) return name + ": no handler";
    if (!seen.insert({route.method, route.path + "\n" + route.action_type}).second) return name + ": declared twice";
  }
  return std::nullopt;
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

void PluginRuntime::start_drivers(const RobotConfig& config) {
  auto log = logger("kernel.plugins");
  for (std::size_t i = 0; i < config.drivers.size(); ++i) {
    const auto& entry = config.drivers[i];
    auto& instance = drivers_.emplace_back();
    instance.id = entry.id;
    instance.protocol = entry.protocol;

    auto [registered, plugin] =
        find_loaded(host_, host_.providers_of_driver(entry.protocol), &PluginRecord::drivers, entry.protocol);
    if (registered == nullptr) {
      instance.health.mark_failed(plugin == nullptr ? "no installed plugin provides driver protocol '" + entry.protocol + "'"
                                                    : "plugin " + plugin->id + " is " + std::string(to_string(plugin->state)) +
                                                          ": " + plugin->reason);
      log->error("driver {}: {}", entry.id, instance.health.reason());
      continue;
    }
    instance.plugin_id = plugin->id;
    instance.actuates = registered->info.actuates;
    auto settings = validated_settings(config, *plugin, entry.settings, true, "drivers[" + std::to_string(i) + "]");
    instance.context = std::make_unique<InstanceContext>(plugin->id, entry.id, services_, std::move(settings), instance.health);

    instance.who = "plugin " + plugin->id + " driver " + entry.id;
    bool abandoned = false;
    instance.object = create_and_start(instance.who, registered->factory, *instance.context, instance.health,
                                       std::chrono::milliseconds(config.runtime.plugin_start_timeout_ms), abandoned);
    if (abandoned) keep_forever(instance.context);  // still in use by the plugin thread that never returned
    if (!instance.object) continue;

    if (instance.actuates) {
      auto* actuator = dynamic_cast<sdk::ActuatorDriver*>(instance.object.get());
      if (actuator == nullptr) {
        instance.health.mark_failed("registered as actuating but is not an ActuatorDriver");
        continue;
      }
      actuators_.add(entry.id, std::string(actuator->interface_name()), plugin->id, actuator, &instance.health);
    }
    if (!instance.health.failed()) offer_obstacle_source(services_, instance.object.get(), "driver " + entry.id);
    log->info("driver {} ({}, {}) {}", entry.id, entry.protocol, plugin->id,
              instance.health.failed() ? "failed: " + instance.health.reason() : "started");
  }
}

void PluginRuntime::start_capabilities(const std::vector<std::string>& names, const RobotConfig& config) {
  auto log = logger("kernel.plugins");
  for (const auto& name : names) {
    if (name == kStatusCapability) continue;  // the kernel's own
    auto [registered, plugin] = find_loaded(host_, host_.providers_of_capability(name), &PluginRecord::capabilities, name);
    auto& instance = capabilities_.emplace_back();
    instance.name = name;
    if (registered == nullptr) {
      instance.health.mark_failed(plugin == nullptr ? "no installed plugin provides it"
                                                    : "plugin " + plugin->id + " is " + std::string(to_string(plugin->state)) +
                                                          ": " + plugin->reason);
      log->error("capability {}: {}", name, instance.health.reason());
      continue;
    }
    instance.plugin_id = plugin->id;
    instance.actuates = registered->info.actuates;
    if (const auto missing = missing_requirement(*plugin)) {
      instance.health.mark_failed("requires a " + *missing + " actuator, and no configured driver provides one");
      log->error("capability {}: {}", name, instance.health.reason());
      continue;
    }
    const nlohmann::json raw =
        config.runtime.capabilities.contains(name) ? config.runtime.capabilities.at(name) : nlohmann::json::object();
    auto settings = validated_settings(config, *plugin, raw, false, "runtime.capabilities." + name);
    instance.context = std::make_unique<InstanceContext>(plugin->id, name, services_, std::move(settings), instance.health);
    instance.handler_worker = std::make_unique<WorkerThread>(
        "cap." + name, [&health = instance.health](const std::string& why) { health.mark_failed(why); });

    instance.who = "plugin " + plugin->id + " capability " + name;
    bool abandoned = false;
    std::vector<sdk::Route> routes;
    instance.object =
        create_and_start<sdk::Capability>(instance.who, registered->factory, *instance.context, instance.health,
                                          std::chrono::milliseconds(config.runtime.plugin_start_timeout_ms), abandoned,
                                          [&routes](sdk::Capability& object) { routes = object.routes(); });
    if (abandoned) keep_forever(instance.context);  // still in use by the plugin thread that never returned
    if (!instance.object) continue;
    if (!instance.health.failed()) {
      if (auto problem = route_problem(routes)) instance.health.mark_failed("routes() returned an unusable route: " + *problem);
      else instance.routes = std::move(routes);
    }
    if (!instance.health.failed()) offer_obstacle_source(services_, instance.object.get(), "capability " + name);
    log->info("capability {} ({}) {}, {} routes", name, plugin->id,
              instance.health.failed() ? "failed: " + instance.health.reason() : "started", instance.routes.size());
  }
  start_crews();
}

std::optional<nlohmann::json> PluginRuntime::status_at(std::size_t index) {
  if (!status_reader_ || index == kNoStatus) return std::nullopt;
  return status_reader_->read(index);
}

std::vector<std::optional<nlohmann::json>> PluginRuntime::capability_statuses() {
  std::vector<std::size_t> indices;
  for (const auto& instance : capabilities_) indices.push_back(instance.health.failed() ? kNoStatus : instance.status_index);
  if (!status_reader_) return std::vector<std::optional<nlohmann::json>>(indices.size());
  return status_reader_->read(indices);
}

std::optional<std::string> PluginRuntime::missing_requirement(const PluginRecord& plugin) const {
  if (!plugin.manifest) return std::nullopt;
  for (const auto& interface : plugin.manifest->requires_) {
    bool provided = false;
    for (const auto& slot : actuators_.slots()) provided = provided || slot.interface == interface;
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
  if (!estop_crew_) {
    for (auto& instance : capabilities_)
      if (instance.object) instance.object->on_estop();
    return;
  }
  for (const auto& outcome : estop_crew_->run_all(std::chrono::steady_clock::now() + kEstopNotifyDeadline)) {
    if (outcome.state == DeadlineCrew::State::Done) continue;
    try {
      const std::string why = outcome.state == DeadlineCrew::State::Failed
                                  ? "on_estop() threw: " + outcome.error
                                  : "on_estop() did not return within " + std::to_string(kEstopNotifyDeadline.count()) + " ms";
      logger("kernel.plugins")->error("capability {}: {}", outcome.name, why);
      if (auto* instance = capability(outcome.name); instance != nullptr && outcome.state == DeadlineCrew::State::Failed)
        instance->health.mark_failed(why);
    } catch (...) {  // reporting must never undo the stop
    }
  }
}

namespace {

// Every instance's shutdown() in parallel on a crew of its own, waited for up to `deadline`; then the workers of
// each instance whose hook returned are joined. A hook that throws out of its noexcept is contained and logged;
// one still running at the deadline is logged and left running, and true is returned: its object and context must
// never be destroyed.
template <class Instances> bool shut_down_all(Instances& instances, std::chrono::milliseconds deadline) noexcept {
  std::vector<typename Instances::value_type*> members;
  std::optional<DeadlineCrew> crew;
  try {
    std::vector<DeadlineCrew::Job> jobs;
    for (auto& instance : instances) {
      if (!instance.object) continue;
      jobs.push_back({instance.who, [object = instance.object.get()] { object->shutdown(); }});
      members.push_back(&instance);
    }
    crew.emplace("shutdown", std::move(jobs));
  } catch (...) {  // no memory or no threads for the crew: shut down inline, as a last resort
    for (auto& instance : instances)
      if (instance.object) instance.object->shutdown();
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

}  // namespace

void PluginRuntime::shutdown() noexcept {
  if (shut_down_) return;
  shut_down_ = true;
  if (estop_crew_ && !estop_crew_->quiesce(std::chrono::milliseconds(500))) abandon_capabilities_ = true;
  for (auto& instance : capabilities_)
    if (instance.handler_worker) instance.handler_worker->join();
  if (shut_down_all(capabilities_, kShutdownDeadline)) abandon_capabilities_ = true;
  if (shut_down_all(drivers_, kShutdownDeadline)) abandon_drivers_ = true;
}

// The threads every started instance gets from the kernel: an on_estop() caller each (the stop path's notify crew)
// and a status() reader each.
void PluginRuntime::start_crews() {
  std::vector<DeadlineCrew::Job> jobs;
  for (auto& instance : capabilities_)
    if (instance.object) jobs.push_back({instance.name, [object = instance.object.get()] { object->on_estop(); }});
  estop_crew_ = std::make_unique<DeadlineCrew>("estop.notify", std::move(jobs));

  std::vector<StatusReader::Source> sources;
  auto add_source = [&sources](auto& instance) {
    if (!instance.object) return;
    instance.status_index = sources.size();
    sources.push_back({instance.who, [object = instance.object.get()] { return object->status(); }, &instance.health});
  };
  for (auto& instance : drivers_) add_source(instance);
  for (auto& instance : capabilities_) add_source(instance);
  status_reader_ = std::make_unique<StatusReader>(std::move(sources));
}

}  // namespace rcand::kernel
