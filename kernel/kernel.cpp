#include "kernel/kernel.hpp"

#include <pthread.h>
#include <sys/resource.h>
#include <boost/asio/ip/address.hpp>

#include <algorithm>
#include <atomic>
#include <thread>

#include "kernel/api/api.hpp"
#include "kernel/api/capability_routes.hpp"
#include "kernel/api/kernel_routes.hpp"
#include "kernel/api/request_dispatch.hpp"
#include "kernel/audit/audit_log.hpp"
#include "kernel/auth/authenticator.hpp"
#include "kernel/plugins/plugin_runtime.hpp"
#include "kernel/safety/actuator_table.hpp"
#include "kernel/safety/estop.hpp"
#include "kernel/safety/kernel_motion_gate.hpp"
#include "kernel/safety/state_dir.hpp"
#include "kernel/service.hpp"
#include "kernel/status/status_board.hpp"
#include "libs/base/bounded_text.hpp"
#include "libs/base/keep_forever.hpp"
#include "libs/base/logging.hpp"
#include "libs/base/steady_clock.hpp"
#include "libs/base/stop_path_priority.hpp"
#include "libs/http/server.hpp"
#include "libs/http/tls_context.hpp"
#include "libs/mdns/service_publisher.hpp"
#include "libs/rcan/loopback.hpp"
#include "libs/rcan/ruri.hpp"
#include "libs/rcan/secret_file.hpp"
#include "libs/yaml/config_diff.hpp"

namespace rcand::kernel {
namespace {

// Every connection is a descriptor. Past the open-files limit accept() fails (EMFILE) for everyone, the e-stop
// included, so max_connections is capped below it (with room for the busy lane and rcand's other files) and a low
// limit is named at startup.
std::size_t connections_within_fd_limit(std::size_t configured, std::size_t busy_lane) {
  constexpr std::size_t kOtherFiles = 256;  // plugins, devices, log and audit files, R2R and swarm sockets
  rlimit files{};
  if (getrlimit(RLIMIT_NOFILE, &files) != 0 || files.rlim_cur == RLIM_INFINITY) return configured;
  const std::size_t limit = files.rlim_cur;
  if (configured + busy_lane + kOtherFiles <= limit) return configured;
  const std::size_t fitting = limit > busy_lane + kOtherFiles + 16 ? limit - busy_lane - kOtherFiles : 16;
  logger("kernel")->warn(
      "the open-files limit is {} (ulimit -n; LimitNOFILE= under systemd): runtime.max_connections {} "
      "is served as {} so that a stop can still be accepted; raise the limit to serve more",
      limit, configured, fitting);
  return fitting;
}

AuthSettings auth_settings(const config::RobotConfig& config, const std::string& ruri, const std::string& address) {
  AuthSettings settings;
  settings.robot_ruri = ruri;
  if (const auto parsed = parse_ruri(ruri).ruri) settings.device_id = parsed->device_id;
  const auto& auth = config.runtime.auth;
  if (auth.mode == "open") {
    // docs/protocol.md §3 ruling: no-auth mode exists only on loopback.
    if (!is_loopback_address(address))
      throw StartupError(
          "runtime.auth.mode is \"open\" (no authentication), which rcand allows only on a loopback "
          "address; runtime.listen.address is " +
          address);
    settings.open_mode = true;
    logger("kernel.auth")->warn("authentication is OFF (runtime.auth.mode: open); listening on loopback only");
  }
  if (auth.jwt_secret_file && config.enable_jwt) {
    auto secret = read_secret_file(*auth.jwt_secret_file);
    if (!secret.secret) throw StartupError("runtime.auth.jwt_secret_file: " + secret.error);
    if (!secret.warning.empty()) logger("kernel.auth")->warn("runtime.auth.jwt_secret_file: {}", secret.warning);
    if (secret.development && !is_loopback_address(address))  // public: anyone who can reach rcand can sign tokens
      logger("kernel.auth")->warn("runtime.auth.jwt_secret_file is the public development secret, off loopback");
    settings.jwt_secret = std::move(secret.secret);
  }
  for (const auto& token : auth.tokens)
    settings.tokens.push_back({token.principal, sdk::parse_role(token.role).value_or(sdk::Role::Guest), token.sha256_hex});
  if (!settings.open_mode && !settings.jwt_secret && settings.tokens.empty())
    logger("kernel.auth")->warn("no tokens and no JWT secret configured: every authenticated endpoint answers 401");
  return settings;
}

// docs/protocol.md §3.9: the robot's own pages and runtime.listen.allowed_origins; its names are the machine's and
// metadata.robot_name.local.
http::OriginPolicy origin_policy(const config::RobotConfig& config) {
  try {
    return http::OriginPolicy({config.runtime.allowed_origins, http::OriginPolicy::own_host_names(config.robot_name)});
  } catch (const std::invalid_argument& e) {  // the schema refuses such an origin first
    throw StartupError(e.what());
  }
}

// runtime.listen.tls as the HTTP server takes it; its files are read (and every problem named) by make_server_tls_context.
std::optional<http::TlsSettings> tls_settings(const config::RobotConfig& config) {
  const auto& tls = config.runtime.listen_tls;
  if (!tls) return std::nullopt;
  return http::TlsSettings{tls->cert_file, tls->key_file, tls->client_ca_file};
}

// What the capability registry plans with: the installed plugins' manifests (none is opened yet).
ProviderLookup installed_providers(const PluginHost& host) {
  ProviderLookup lookup;
  lookup.driver_interface = [&host](std::string_view protocol) -> std::optional<std::string> {
    for (const auto* plugin : host.providers_of_driver(protocol))
      if (const auto* item = find_provided(*plugin->manifest, "driver", protocol); item && !item->interface.empty())
        return item->interface;
    return std::nullopt;
  };
  lookup.driver_implies = [&host](std::string_view protocol) {
    for (const auto* plugin : host.providers_of_driver(protocol))
      if (const auto* item = find_provided(*plugin->manifest, "driver", protocol)) return item->implies;
    return std::vector<DriverImplication>{};
  };
  lookup.providers = [&host](std::string_view capability) {
    std::vector<std::string> found;
    for (const auto* plugin : host.providers_of_capability(capability)) found.push_back(plugin->id);
    return found;
  };
  lookup.declared_when = [&host] {
    std::vector<std::pair<std::string, std::string>> found;
    for (const auto& record : host.records())
      if (record->manifest)
        for (const auto& declared : record->manifest->declared_when)
          if (!host.providers_of_capability(declared.capability).empty())
            found.emplace_back(declared.capability, declared.config_key);
    return found;
  };
  return lookup;
}

}  // namespace

std::vector<std::filesystem::path> default_plugin_paths() { return {"/usr/local/lib/rcand/plugins", RCAND_DEFAULT_PLUGIN_DIR}; }

// The kernel's parts. The values on top are built in declaration order, each from the ones above it; every part
// below is made by Kernel() or claim_robot() and destroyed by ~State() in the order stated there, whatever the order
// here. Stopping them is Kernel::shutdown()'s.
struct Kernel::State {
  config::RobotConfig config;
  std::string address;
  std::uint16_t port = 0;
  std::atomic<std::uint16_t> bound_port{0};
  std::int64_t started_us = 0;
  SteadyClock clock;
  sdk::ConfigView robot_config_view;
  ActuatorTable actuators;
  Estop estop{clock, actuators};
  KernelMotionGate gate{actuators, estop};
  KernelServices services{clock, estop, gate, robot_config_view, &audit, {}, {}};  // audit: address only
  AuditLog audit;
  PluginHost host;

  std::unique_ptr<StateDir> state_dir;             // runtime.state_dir, locked by claim_robot() (not when embedded)
  std::atomic<StateDir*> state_dir_live{nullptr};  // the e-stop listeners' view: set once the latch is restored
  std::unique_ptr<Authenticator> auth;
  std::unique_ptr<CapabilityRegistry> registry;
  std::unique_ptr<Api> api;
  std::unique_ptr<KernelRequestDispatcher> dispatcher;  // offered to plugins: requests on a caller's behalf
  std::unique_ptr<ServiceHost> service_host;
  std::vector<std::unique_ptr<Service>> optional_services;
  std::unique_ptr<PluginRuntime> runtime;
  std::unique_ptr<DeadlineCrew> halt_crew;  // one thread per actuator: the stop path's parallel halt() calls
  std::unique_ptr<WorkerThread> timers;
  std::unique_ptr<WorkerThread> reloader;   // "plugin.reload", only with runtime.plugins.allow_reload: one reload at a time
  std::atomic<bool> reloads_closed{false};  // set by shutdown(): a queued reload answers 503
  // The capabilities start on this thread once rcand serves (start()); `capabilities_up` is set when every one is up
  // or failed (reloads wait for it), `stop_starting` by shutdown() (the rest fail without starting).
  std::thread starter;
  std::atomic<bool> capabilities_up{false}, stop_starting{false};
  std::function<void()> on_capabilities_up;
  std::unique_ptr<KernelRouteDeps> kernel_routes;
  std::unique_ptr<CapabilityRouteDeps> capability_routes;
  std::unique_ptr<SlotTable> stream_slots;     // streamed answers held at once (runtime.max_streams_per_*)
  std::unique_ptr<StatusBoard> status_board;   // GET /api/status, discovery, mDNS TXT and R2R status read it
  std::unique_ptr<http::Server> server;        // bound by claim_robot(), serving from start()
  std::vector<http::UpgradeHandler> upgrades;  // the services' WebSocket upgrades: set by start() before it serves
  std::unique_ptr<mdns::ServicePublisher> mdns_publisher;
  bool shut_down = false;

  ~State();
  void claim_robot();
  http::ServerOptions server_options();
  void load_plugins(const KernelOptions& options);
  void create_services(const KernelOptions& options);
  void start_plugins();
  void start_capabilities();
  void tell_services();
  void add_routes();
  void restore_latch();
  bool reload_tls(const config::RobotConfig& next);
  void reload_plugin(const std::string& id, const std::string& principal, std::function<void(int, nlohmann::json)> done);
};

// Each part goes before what it uses: the state dir first (its writer reads the e-stop), the readers of the status
// (mDNS, the server and its WebSocket upgrades) before it, and it before the plugins it polls; the threads that call
// into plugins (reloads, timers, halts; shutdown() joined the starter) before the plugins; the plugins before the
// services that lend them R2R links; the request path last. The values above the parts outlive them all.
Kernel::State::~State() {
  state_dir_live = nullptr;
  state_dir.reset();
  mdns_publisher.reset();
  upgrades.clear();
  server.reset();
  status_board.reset();
  stream_slots.reset();
  capability_routes.reset();
  kernel_routes.reset();
  reloader.reset();
  timers.reset();
  halt_crew.reset();
  runtime.reset();
  optional_services.clear();
  service_host.reset();
  dispatcher.reset();
  api.reset();
  registry.reset();
  auth.reset();
}

// Manifests only: nothing is opened until we know what the config needs. Then the registry, and the robot config as
// plugins see it.
void Kernel::State::load_plugins(const KernelOptions& options) {
  auto log = logger("kernel");
  auto plugin_paths = options.plugin_paths.value_or(config.runtime.plugin_paths);
  host.scan(plugin_paths.empty() ? default_plugin_paths() : plugin_paths);
  host.set_reload_parent(config.runtime.state_dir);
  // A name other runtimes write is rcand's alias only while no installed plugin provides that name itself.
  for (auto& driver : config.drivers)
    if (!driver.written_protocol.empty() && !host.providers_of_driver(driver.written_protocol).empty()) {
      log->info("driver {}: protocol '{}' is served by plugin {}, which provides it (not read as '{}')", driver.id,
                driver.written_protocol, host.providers_of_driver(driver.written_protocol).front()->id, driver.protocol);
      driver.settings["protocol"] = driver.protocol = driver.written_protocol;
    }
  CapabilityPlan plan = plan_capabilities(config, installed_providers(host));
  for (const auto& note : plan.notes) log->info("{}", note);

  std::set<std::string> capabilities(plan.names.begin(), plan.names.end());
  capabilities.insert(plan.unadvertised.begin(), plan.unadvertised.end());
  capabilities.erase(std::string(kStatusCapability));
  std::set<std::string> protocols;
  for (const auto& driver : config.drivers) protocols.insert(driver.protocol);
  host.set_register_timeout(std::chrono::milliseconds(config.runtime.plugin_start_timeout_ms));
  host.load_needed(capabilities, protocols, &config.runtime.capabilities);
  for (const auto& record : host.records())
    if (is_failure(record->state))
      log->error("plugin {} ({}): {} — {}{}", record->id, record->manifest_file.string(), to_string(record->state),
                 record->reason, record->hint.empty() ? "" : " (hint: " + record->hint + ")");
  registry = std::make_unique<CapabilityRegistry>(RobotIdentity{services.ruri, config.robot_name, config.model}, std::move(plan));
  // Plugins see the robot config without rcand's own auth settings, and with rcan_protocol.capabilities as declared
  // (auto-detected ones filled in): what this robot may bid with, for one.
  nlohmann::json visible = config.doc;
  if (visible.contains("runtime") && visible["runtime"].is_object()) visible["runtime"].erase("auth");
  visible["rcan_protocol"]["capabilities"] = registry->names();
  robot_config_view = sdk::ConfigView(std::move(visible));
}

void Kernel::State::create_services(const KernelOptions& options) {
  service_host.reset(new ServiceHost{config, *auth, estop, audit, clock, *registry, *api,
                                     std::chrono::milliseconds(config.runtime.handler_timeout_ms),
                                     [this] { return status_board->document(); }, [this] { return status_board->robot_state(); },
                                     bound_port, services.directory});
  for (const auto& make : options.services)
    if (auto service = make(*service_host)) optional_services.push_back(std::move(service));
}

void Kernel::State::start_plugins() {
  runtime->start_drivers(config);
  std::vector<DeadlineCrew::Job> halts;
  for (const auto& slot : actuators.slots())
    halts.push_back({slot.id, [slot = &slot] { halt_slot(*slot); }});  // whichever driver object serves it then
  halt_crew = std::make_unique<DeadlineCrew>(
      "estop.halt", std::move(halts), [priority = config.runtime.stop_path_priority] { enter_stop_path_priority(priority); });
  estop.use_halt_crew(halt_crew.get());
  runtime->declare_capabilities(registry->served(), config);  // started by start_capabilities(), or below when embedded
  if (!server) {
    runtime->start_declared(config, [] { return true; }, {});
    tell_services();
    capabilities_up = true;
  }
  estop.on_latched([runtime = runtime.get()] { runtime->notify_estop(); });
  // The latch record in runtime.state_dir follows every latch and clear (written off the stop path).
  estop.on_latched([this] {
    if (auto* state = state_dir_live.load()) state->latch_changed();
  });
  estop.on_cleared([this] {
    if (auto* state = state_dir_live.load()) state->latch_changed();
    audit.end_repeats();  // the next stop is no repeat: a new audit entry
  });
  if (config.estop_on_startup)
    estop.latch("safety.estop_on_startup", "config", {{}, "startup", {}, "safety.estop_on_startup is set"});
}

// The route table: the kernel's rows, the capabilities' rows, then each service's (which may wrap the others).
void Kernel::State::add_routes() {
  kernel_routes.reset(new KernelRouteDeps{
      clock, estop, audit, host, *runtime, std::string(kRcandVersion), started_us, *status_board,
      [this] { return registry->advertise(status_board->robot_state(), bound_port.load()).discover; },
      [this](const std::string& id, const std::string& principal, auto done) { reload_plugin(id, principal, std::move(done)); }});
  add_kernel_routes(api->router(), *kernel_routes);
  stream_slots = std::make_unique<SlotTable>(
      SlotLimits{SlotLimits::kUnlimited, 0, config.runtime.max_streams_per_principal, config.runtime.max_streams_per_address});
  capability_routes.reset(new CapabilityRouteDeps{*registry, *runtime, audit, estop, *timers,
                                                  std::chrono::milliseconds(config.runtime.handler_timeout_ms), *stream_slots,
                                                  *auth});
  install_capability_routes(api->router(), *capability_routes);
  for (auto& service : optional_services) service->add_routes(api->router());
}

// POST /api/plugins/<id>/reload (docs/protocol.md §7.15): refused unless runtime.plugins.allow_reload; otherwise on the
// reload worker, never during shutdown: every driver halted through the e-stop latch, then PluginRuntime::reload. The
// e-stop stays latched (an operator clears it).
void Kernel::State::reload_plugin(const std::string& id, const std::string& principal,
                                  std::function<void(int, nlohmann::json)> done) {
  if (!reloader)
    return done(409,
                {{"code", "RELOAD_DISABLED"},
                 {"error", "plugin reload is off on this robot; development robots set runtime.plugins.allow_reload: true"}});
  reloader->post([this, id, principal, done = std::move(done)] {
    capabilities_up.wait(false);  // a reload never runs while capabilities start
    if (reloads_closed) return done(503, {{"code", "UNAVAILABLE"}, {"error", "rcand is shutting down"}});
    nlohmann::json body{{"plugin", bounded_text(id)}, {"estopped", false}};  // the id is the caller's, from the path
    const ReloadResult result = runtime->reload(id, config, [&] {
      const auto halt = estop.latch("plugin reload: " + id, principal, {principal, "reload", id, {}});
      body["estopped"] = true;
      body["motors_stopped"] = std::all_of(halt.drivers.begin(), halt.drivers.end(), [](const auto& d) { return d.halted; });
    });
    if (const PluginRecord* record = host.find(id))
      body.update({{"state", to_string(record->state)}, {"version", record->version}, {"build_info", record->build_info}});
    body["instances"] = result.instances;
    if (result.status != 200) body.update({{"code", result.code}, {"error", result.error}});
    status_board->refresh();  // the answer's reader sees the reloaded instances
    tell_services();
    done(result.status, std::move(body));
  });
}

// Plugin instances started or were reloaded: the services re-read what plugins offer.
void Kernel::State::tell_services() {
  for (auto& service : optional_services) service->capabilities_changed();
}

// Off the thread that serves, in the order they are declared: each capability's routes installed and the status told
// as it comes up (or fails).
void Kernel::State::start_capabilities() {
  starter = std::thread([this] {
    pthread_setname_np(pthread_self(), "kernel.starter");
    runtime->start_declared(
        config, [this] { return !stop_starting.load(); },
        [this](CapabilityInstance&) {
          try {
            install_capability_routes(api->router(), *capability_routes);
          } catch (const std::exception& e) {  // a row clashing with another group's: a programming error, named
            logger("kernel.api")->error("capability routes: {}", e.what());
          }
          status_board->notify();
          tell_services();
        });
    status_board->refresh();  // read after "capabilities started", the status shows each as it ended up
    capabilities_up = true;
    capabilities_up.notify_all();
    if (on_capabilities_up && !stop_starting.load()) on_capabilities_up();
  });
}

Kernel::Kernel(config::RobotConfig config, KernelOptions options) : state_(std::make_unique<State>()) {
  auto& s = *state_;
  s.config = std::move(config);
  s.on_capabilities_up = std::move(options.on_capabilities_up);
  const auto& cfg = s.config;
  s.address = cfg.runtime.listen_address;
  s.port = options.port.value_or(cfg.listen_port());
  s.started_us = s.clock.now_us();
  if (!options.embedded) s.claim_robot();  // before anything that writes or opens a device (docs/protocol.md §6.9)

  s.services.ruri = robot_ruri(cfg.ruri, cfg.manufacturer, cfg.model, cfg.robot_uuid);
  s.auth = std::make_unique<Authenticator>(auth_settings(cfg, s.services.ruri, s.address));
  s.audit.identify(s.services.ruri, s.clock);
  if (cfg.runtime.audit_file) {
    try {
      s.audit.persist_to(*cfg.runtime.audit_file, cfg.runtime.audit_max_bytes, cfg.runtime.audit_keep_files);
    } catch (const std::runtime_error& e) {
      throw StartupError(e.what());
    }
  }
  s.load_plugins(options);
  s.runtime = std::make_unique<PluginRuntime>(s.host, s.services, s.actuators);
  s.api = std::make_unique<Api>(cfg.runtime, *s.auth, s.audit, s.estop, s.clock, origin_policy(cfg));
  s.dispatcher = std::make_unique<KernelRequestDispatcher>(*s.api);
  s.services.directory.offer_service(sdk::RequestDispatcher::kServiceId,
                                     static_cast<const sdk::RequestDispatcher*>(s.dispatcher.get()), nullptr, "rcand", nullptr);
  s.create_services(options);  // before the plugins: R2R offers them links
  if (auto problems = s.runtime->plan_problems(cfg, s.registry->served()); !problems.empty())
    throw yaml::ConfigError(std::move(problems));
  s.start_plugins();
  s.timers = std::make_unique<WorkerThread>("kernel.timers", nullptr);
  if (cfg.doc.is_object() && cfg.doc.value(nlohmann::json::json_pointer("/runtime/plugins/allow_reload"), false))
    s.reloader = std::make_unique<WorkerThread>("plugin.reload", nullptr);
  // The status snapshot plugins publish into; GET /api/status never calls plugin code.
  s.status_board = std::make_unique<StatusBoard>(
      *s.runtime, s.services, StatusBoard::fixed_fields(s.registry->identity(), s.registry->names(), s.host, kRcandVersion),
      s.started_us);
  s.status_board->start();
  s.add_routes();
  if (cfg.enable_mdns) {
    s.mdns_publisher = std::make_unique<mdns::ServicePublisher>(logger("kernel.mdns"));
    // TXT "status" follows an e-stop at once, not at the next once-a-second check (never blocks the stop path).
    s.estop.on_latched([publisher = s.mdns_publisher.get()] { publisher->refresh_soon(); });
  }
}

Kernel::~Kernel() { shutdown(); }

Kernel::CheckReport Kernel::check(config::RobotConfig config, const KernelOptions& options) {
  State s;
  s.config = std::move(config);
  s.services.ruri = robot_ruri(s.config.ruri, s.config.manufacturer, s.config.model, s.config.robot_uuid);
  s.auth = std::make_unique<Authenticator>(auth_settings(s.config, s.services.ruri, s.config.runtime.listen_address));
  // The secret and the services' files (the swarm file) are read as at startup: one rcand cannot read fails here too.
  for (const auto& check_files : options.service_checks) check_files(s.config);
  try {
    if (const auto tls = tls_settings(s.config)) http::make_server_tls_context(*tls);
  } catch (const http::TlsError& e) {
    throw StartupError(e.what());
  }
  s.load_plugins(options);
  PluginRuntime runtime(s.host, s.services, s.actuators);
  auto problems = runtime.check(s.config, s.registry->served());
  if (!problems.empty()) throw yaml::ConfigError(std::move(problems));
  CheckReport report{s.registry->names(), {}};
  for (const auto& driver : s.config.drivers)
    for (const auto* plugin : s.host.providers_of_driver(driver.protocol))
      for (const auto& item : plugin->manifest->provides)
        if (item.kind == "driver" && item.name == driver.protocol && item.actuates)
          report.fail_safes.push_back(
              driver.id + " (" + driver.protocol +
              "): " + (item.fail_safe.empty() ? "WARNING: " + plugin->id + " states no hardware fail-safe" : item.fail_safe));
  return report;
}

// One rcand per robot: runtime.state_dir's lock, then the listening port(s), each a StartupError naming what holds
// it. Nothing else of the robot exists yet, so a refused start has opened no device and started no plugin.
void Kernel::State::claim_robot() {
  try {
    state_dir = std::make_unique<StateDir>(config.runtime.state_dir);
    server = std::make_unique<http::Server>(server_options(), [this](http::Request&& request, http::Respond respond) {
      api->handle(std::move(request), std::move(respond));
    });
    port = server->bind();
  } catch (const std::exception& e) {
    throw StartupError(e.what());
  }
}

// runtime.state_dir: the e-stop starts latched when the last run ended without a clean shutdown or while latched,
// with the reason in GET /api/estop and the audit log. Before anything is served.
void Kernel::State::restore_latch() {
  try {
    state_dir->mark_running();
  } catch (const std::runtime_error& e) {
    throw StartupError(e.what());
  }
  const auto& previous = state_dir->previous();
  const bool was_latched = previous.latch && previous.latch->latched;
  std::string why;
  if (previous.unclean_exit) {
    why = "the previous run of rcand ended without a clean shutdown (killed, crashed or lost power; " + previous.marker + ")";
    if (was_latched) why += "; it was latched then: " + previous.latch->reason + " (by " + previous.latch->source + ")";
  } else if (was_latched) {
    why = "latched when rcand last stopped: " + previous.latch->reason + " (by " + previous.latch->source + ")";
  }
  if (!why.empty()) {
    why = bounded_text(why, 600);
    if (estop.latched()) estop.restate(why + "; safety.estop_on_startup is set as well", "startup");
    else estop.latch(why, "startup", {{}, "startup", {}, {}});
    const auto seq = audit.begin("rcand", "startup-" + std::to_string(clock.wall_ms()), "e-stop latched at startup");
    audit.finish(seq, "ok", why);
    logger("kernel.estop")->warn("starting latched: {}", why);
  }
  state_dir->start_writer([this] {
    const auto now = estop.snapshot();
    return StateDir::LatchRecord{now.estopped, now.reason, now.source, now.since_ms};
  });
  state_dir_live.store(state_dir.get());
  state_dir->latch_changed();  // the record says what this run starts with
}

http::ServerOptions Kernel::State::server_options() {
  http::ServerOptions options;
  options.address = address;
  options.port = port;
  options.max_connections = connections_within_fd_limit(config.runtime.max_connections, options.busy_lane);
  options.max_connections_per_address = config.runtime.max_connections_per_address;
  options.tls = tls_settings(config);  // then plain HTTP on loopback only (http/server_options.hpp)
  options.plain_loopback_port = config.runtime.plain_loopback_port;
  // The e-stop is read and handled on the accept thread, ahead of any other work, and is answered even when every
  // connection slot is taken (issue 13: neither load nor a flood may delay or lock out a stop).
  options.on_thread_start = [priority = config.runtime.stop_path_priority](bool accept_loop) {
    if (accept_loop) enter_stop_path_priority(priority);
  };
  options.priority = [](const http::Request& request) {
    return (request.method == "POST" && request.path == "/api/stop") || (request.method == "GET" && request.path == "/api/estop");
  };
  // Every request and upgrade is screened first (Origin, Host: docs/protocol.md §3.9); the Api exists once it serves.
  options.screen = [this](const http::Request& request) { return api->screen(request); };
  options.upgrade = [this](const http::Request& request) {  // WS /ws/r2r, /ws/telemetry on the robot's own port
    for (const auto& upgrade : upgrades)                    // each hook answers only for its own path: the first that does wins
      if (auto verdict = upgrade(request); verdict.take || verdict.refuse) return verdict;
    return http::UpgradeVerdict{};
  };
  return options;
}

std::uint16_t Kernel::start() {
  auto& s = *state_;
  if (!s.server) throw std::logic_error("an embedded kernel (KernelOptions::embedded) does not serve");
  if (!s.state_dir_live.load()) s.restore_latch();
  for (auto& service : s.optional_services)
    if (auto upgrade = service->upgrade()) s.upgrades.push_back(std::move(upgrade));
  try {
    s.port = s.server->start();
  } catch (const std::exception& e) {
    throw StartupError(e.what());
  }
  s.bound_port = s.port;
  for (auto& service : s.optional_services) service->start(s.port);                // throws StartupError naming the setting
  if (!s.starter.joinable() && !s.capabilities_up.load()) s.start_capabilities();  // the latch is restored: serving
  if (s.mdns_publisher) {
    // docs/protocol.md §5: instance metadata.robot_name, the port bound, the TXT record of the one registry function (§9.5).
    s.mdns_publisher->start({.name = s.config.robot_name, .type = std::string(kServiceType), .port = s.port, .txt = [&s] {
                               return s.registry->advertise(s.status_board->robot_state(), s.port).txt;
                             }});
  }
  logger("kernel")->info("{} ({}) serving RCAN {} on http://{}:{} with capabilities [{}]", s.config.robot_name,
                         s.registry->identity().ruri, kRcanVersion, s.address, s.port,
                         s.registry->advertise("idle", s.port).txt.at("caps"));
  return s.port;
}

std::uint16_t Kernel::plain_loopback_port() const { return state_->server ? state_->server->plain_loopback_port() : 0; }

bool Kernel::stop_path_responsive(std::chrono::milliseconds within) const {
  return state_ && state_->server && state_->server->accept_loop_responsive(within);
}

// The stop order, stated once (~State destroys the parts later). Each step runs whatever the one before did: a part
// that fails to stop never leaves the plugins running or the state dir without its clean-exit record.
void Kernel::shutdown() noexcept {
  if (!state_ || state_->shut_down) return;
  auto& s = *state_;
  s.shut_down = true;
  const auto before = s.estop.snapshot();  // what the state dir keeps: the latch as it was, not this one
  const auto step = [](const char* part, const auto& run) noexcept {
    try {
      run();
    } catch (const std::exception& e) {
      logger("kernel")->error("shutdown, {}: {}", part, e.what());
    }
  };
  step("e-stop", [&] { s.estop.latch("rcand shutting down", "kernel", {{}, "shutdown", {}, {}}); });  // motors first
  // Then the services, in reverse: no R2R message is handled or sent, no broadcast goes out.
  step("services", [&] { std::for_each(s.optional_services.rbegin(), s.optional_services.rend(), [](auto& x) { x->stop(); }); });
  // A capability still starting is abandoned (its plugin thread left running, as at plugin_start_timeout_ms); the
  // rest never start.
  step("starter", [&] {
    s.stop_starting = true;
    if (!s.capabilities_up.load()) s.runtime->give_up_starting();
    if (s.starter.joinable()) s.starter.join();
    s.capabilities_up = true;
    s.capabilities_up.notify_all();
  });
  s.reloads_closed = true;
  step("reloads", [&] {
    if (s.reloader) s.reloader->join();
  });  // a reload under way ends first; queued ones answer 503
  step("mDNS", [&] {
    if (s.mdns_publisher) s.mdns_publisher->stop();
  });  // withdrawn while HTTP still answers
  step("HTTP", [&] {
    if (s.server) s.server->stop();
  });
  step("status", [&] { s.status_board->stop(); });  // before the plugins go: it polls them
  // A halt() still running (slow or hung driver) must not have its driver destroyed under it: leak the plugin
  // objects instead (the process is ending).
  step("plugins", [&] {
    const bool halts_quiet = !s.halt_crew || s.halt_crew->quiesce(std::chrono::seconds(2));
    s.runtime->shutdown();
    s.estop.use_halt_crew(nullptr);
    if (halts_quiet) return;
    logger("kernel")->error("a driver's halt() is still running at shutdown; its plugin objects are not destroyed");
    keep_forever(s.runtime);
  });
  step("timers", [&] { s.timers->join(); });
  // Last: a shutdown that does not get here (a crash, the grace timer) leaves the running marker.
  // Only a run that marked the state dir running says how it ended (a start refused later leaves it as it was).
  step("state dir", [&] {
    if (auto* state_dir = s.state_dir_live.exchange(nullptr))
      state_dir->clean_exit({before.estopped, before.reason, before.source, before.since_ms});
  });
}

// SIGHUP: runtime.listen.tls's files are read again even when the config names the same ones (renewed in place), for
// the connections accepted from now on. Throws (nothing changed) when they cannot be used; false when TLS was not on
// at start or is not now: turning it on or off needs a restart.
bool Kernel::State::reload_tls(const config::RobotConfig& next) {
  const auto tls = tls_settings(next);
  if (!tls || !config.runtime.listen_tls || !server) return false;
  server->reload_tls(*tls);
  return true;
}

Kernel::ReloadReport Kernel::reload(const std::filesystem::path& file) noexcept {
  std::vector<std::string> live_keys{"runtime.auth", "runtime.logging"};
  auto& s = *state_;
  ReloadReport report;
  auto log = logger("kernel");
  std::optional<std::string> new_log_level;
  try {
    // Everything that can fail is read and checked before anything changes.
    config::LoadedConfig loaded = config::load_robot_config(file);
    const config::RobotConfig& next = loaded.config;
    AuthSettings auth = auth_settings(next, s.services.ruri, s.address);
    std::vector<ServiceReload> service_reloads;
    for (auto& service : s.optional_services) service_reloads.push_back(service->prepare_reload(next));
    const bool tls_live = s.reload_tls(next);
    s.auth->replace(std::move(auth));
    new_log_level = next.runtime.log_level;  // applied after this reload's own log line
    for (auto& service : service_reloads) {
      if (service.apply) service.apply();
      live_keys.insert(live_keys.end(), service.live_keys.begin(), service.live_keys.end());
    }
    for (const auto& warning : loaded.warnings) log->warn("{}", warning.format());
    for (auto& key : changed_keys(s.config.doc, next.doc)) {
      const bool live = std::any_of(live_keys.begin(), live_keys.end(), [&](const auto& p) { return key_is_under(key, p); }) ||
                        (tls_live && key_is_under(key, "runtime.listen.tls"));
      (live ? report.applied : report.needs_restart).push_back(std::move(key));
    }
    report.ok = true;
  } catch (const yaml::ConfigError& e) {
    for (const auto& diagnostic : e.diagnostics()) report.errors.push_back(diagnostic.format());
  } catch (const std::exception& e) {
    report.errors.emplace_back(file.string() + ": " + e.what());
  }
  try {
    auto join = [](const std::vector<std::string>& items) {
      std::string text;
      for (const auto& item : items) text += (text.empty() ? "" : ", ") + item;
      return text.empty() ? std::string("none") : text;
    };
    const std::string detail = report.ok ? "applied: " + join(report.applied) + "; needs a restart: " + join(report.needs_restart)
                                         : "invalid, still running on the previous config: " + join(report.errors);
    // docs/protocol.md §6.3: a config change is audited like a command (before the log line that announces it).
    const auto seq = s.audit.begin("SIGHUP", "reload-" + std::to_string(s.clock.wall_ms()), "config reload");
    s.audit.finish(seq, report.ok ? "ok" : "error", detail.substr(0, 2000));
    if (!report.ok) {
      for (const auto& error : report.errors) log->error("{}", error);
      log->error("config reload from {}: invalid; still running on the previous config", file.string());
    } else {
      log->info("config reload from {}: {}", file.string(), detail);
    }
    if (new_log_level) configure_logging(*new_log_level);
  } catch (...) {  // reporting must not take the robot down
  }
  return report;
}

const PluginHost& Kernel::plugins() const noexcept { return state_->host; }
const CapabilityRegistry& Kernel::registry() const noexcept { return *state_->registry; }
Api& Kernel::api() noexcept { return *state_->api; }

}  // namespace rcand::kernel
