#include "kernel/kernel.hpp"

#include <boost/asio/ip/address.hpp>
#include <sys/resource.h>

#include <algorithm>
#include <atomic>

#include "kernel/auth/authenticator.hpp"
#include "libs/rcan/ruri.hpp"
#include "libs/rcan/secret_file.hpp"
#include "kernel/config/config_diff.hpp"
#include "kernel/safety/actuator_table.hpp"
#include "kernel/api/api.hpp"
#include "kernel/audit/audit_log.hpp"
#include "kernel/safety/estop.hpp"
#include "kernel/plugins/keep_forever.hpp"
#include "kernel/safety/kernel_motion_gate.hpp"
#include "libs/base/logging.hpp"
#include "libs/rcan/loopback.hpp"
#include "kernel/plugins/plugin_runtime.hpp"
#include "services/r2r/r2r_service.hpp"
#include "kernel/safety/state_dir.hpp"
#include "kernel/safety/stop_path_priority.hpp"
#include "kernel/steady_clock.hpp"
#include "libs/http/server.hpp"
#include "libs/mdns/host_resolver.hpp"
#include "libs/mdns/service_publisher.hpp"
#include "libs/swarm/fan_out.hpp"
#include "libs/swarm/swarm_registry.hpp"
#include "libs/base/bounded_text.hpp"

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
  logger("kernel")->warn("the open-files limit is {} (ulimit -n; LimitNOFILE= under systemd): runtime.max_connections {} "
                         "is served as {} so that a stop can still be accepted; raise the limit to serve more",
                         limit, configured, fitting);
  return fitting;
}

AuthSettings auth_settings(const RobotConfig& config, const std::string& ruri, const std::string& address) {
  AuthSettings settings;
  settings.robot_ruri = ruri;
  if (const auto parsed = parse_ruri(ruri).ruri) settings.device_id = parsed->device_id;
  const auto& auth = config.runtime.auth;
  if (auth.mode == "open") {
    // docs/protocol.md §3 ruling: no-auth mode exists only on loopback.
    if (!is_loopback_address(address))
      throw StartupError("runtime.auth.mode is \"open\" (no authentication), which rcand allows only on a loopback "
                         "address; runtime.listen.address is " + address);
    settings.open_mode = true;
    logger("kernel.auth")->warn("authentication is OFF (runtime.auth.mode: open); listening on loopback only");
  }
  if (auth.jwt_secret_file && config.enable_jwt) {
    auto secret = read_secret_file(*auth.jwt_secret_file);
    if (!secret.secret) throw StartupError("runtime.auth.jwt_secret_file: " + secret.error);
    settings.jwt_secret = std::move(secret.secret);
  }
  for (const auto& token : auth.tokens)
    settings.tokens.push_back({token.principal, sdk::parse_role(token.role).value_or(sdk::Role::Guest), token.sha256_hex});
  if (!settings.open_mode && !settings.jwt_secret && settings.tokens.empty())
    logger("kernel.auth")->warn("no tokens and no JWT secret configured: every authenticated endpoint answers 401");
  return settings;
}

}  // namespace

std::vector<std::filesystem::path> default_plugin_paths() {
  return {"/usr/local/lib/rcand/plugins", RCAND_DEFAULT_PLUGIN_DIR};
}

struct Kernel::State {
  RobotConfig config;
  std::string address;
  std::uint16_t port = 0;
  SteadyClock clock;
  sdk::ConfigView robot_config_view;
  ActuatorTable actuators;
  Estop estop{clock, actuators};
  KernelMotionGate gate{actuators, estop};
  KernelServices services{clock, estop, gate, robot_config_view, &audit, {}, {}};  // audit: address only
  AuditLog audit;
  PluginHost host;
  r2r::PluginBridge r2r_bridge;  // plugins' R2R links: declared before the plugin runtime, so it outlives them
  std::unique_ptr<Authenticator> auth;
  std::unique_ptr<CapabilityRegistry> registry;
  std::unique_ptr<PluginRuntime> runtime;
  std::unique_ptr<DeadlineCrew> halt_crew;  // one thread per actuator: the stop path's parallel halt() calls
  std::unique_ptr<WorkerThread> timers;
  std::unique_ptr<ApiContext> api_context;
  std::unique_ptr<Api> api;
  std::unique_ptr<R2rService> r2r;  // uses the Api: declared after it, destroyed before it
  std::unique_ptr<http::Server> server;
  swarm::SwarmRegistry swarm;
  std::vector<std::unique_ptr<swarm::SwarmRegistry>> retired_swarms;  // reloaded ones; never freed while serving
  std::shared_ptr<mdns::AvahiHostResolver> mdns_resolver;  // swarm "*.local" hosts; shared with the fan-out
  std::unique_ptr<swarm::FanOut> fan_out;  // declared after the Api's context: stopped and destroyed before it
  std::unique_ptr<mdns::ServicePublisher> mdns_publisher;  // reads the Api: declared after it, destroyed before it
  bool shut_down = false;
  // runtime.state_dir, opened by start() (a kernel that never serves, --check-config say, leaves it alone). Last:
  // destroyed first, its writer reads the e-stop.
  std::unique_ptr<StateDir> state_dir;
  std::atomic<StateDir*> state_dir_live{nullptr};  // the e-stop listeners' view: set once the latch is restored
};

Kernel::Kernel(RobotConfig config, KernelOptions options) : state_(std::make_unique<State>()) {
  auto& s = *state_;
  s.config = std::move(config);
  const auto& cfg = s.config;
  s.address = cfg.runtime.listen_address;
  s.port = options.port.value_or(cfg.listen_port());
  auto log = logger("kernel");

  // Plugins see the robot config without rcand's own auth settings.
  nlohmann::json visible = cfg.doc;
  if (visible.contains("runtime") && visible["runtime"].is_object()) visible["runtime"].erase("auth");
  s.robot_config_view = sdk::ConfigView(std::move(visible));

  const std::string ruri = robot_ruri(cfg.ruri, cfg.manufacturer, cfg.model, cfg.robot_uuid);
  s.auth = std::make_unique<Authenticator>(auth_settings(cfg, ruri, s.address));
  if (cfg.runtime.audit_file) {
    try {
      s.audit.persist_to(*cfg.runtime.audit_file, cfg.runtime.audit_max_bytes, cfg.runtime.audit_keep_files);
    } catch (const std::runtime_error& e) {
      throw StartupError(e.what());
    }
  }
  s.services.ruri = ruri;

  // Manifests only: nothing is opened until we know what the config needs.
  auto plugin_paths = options.plugin_paths.value_or(cfg.runtime.plugin_paths);
  s.host.scan(plugin_paths.empty() ? default_plugin_paths() : plugin_paths);
  ProviderLookup lookup;
  lookup.driver_interface = [&s](std::string_view protocol) -> std::optional<std::string> {
    for (const auto* plugin : s.host.providers_of_driver(protocol))
      for (const auto& item : plugin->manifest->provides)
        if (item.kind == "driver" && item.name == protocol && !item.interface.empty()) return item.interface;
    return std::nullopt;
  };
  lookup.providers = [&s](std::string_view capability) {
    std::vector<std::string> found;
    for (const auto* plugin : s.host.providers_of_capability(capability)) found.push_back(plugin->id);
    return found;
  };
  CapabilityPlan plan = plan_capabilities(cfg, lookup);
  for (const auto& note : plan.notes) log->info("{}", note);

  std::set<std::string> capabilities(plan.names.begin(), plan.names.end());
  capabilities.erase("status");
  std::set<std::string> protocols;
  for (const auto& driver : cfg.drivers) protocols.insert(driver.protocol);
  s.host.set_register_timeout(std::chrono::milliseconds(cfg.runtime.plugin_start_timeout_ms));
  s.host.load_needed(capabilities, protocols);
  for (const auto& record : s.host.records())
    if (is_failure(record->state))
      log->error("plugin {} ({}): {} — {}{}", record->id, record->manifest_file.string(), to_string(record->state),
                 record->reason, record->hint.empty() ? "" : " (hint: " + record->hint + ")");

  s.registry = std::make_unique<CapabilityRegistry>(RobotIdentity{ruri, cfg.robot_name, cfg.model}, std::move(plan));
  s.runtime = std::make_unique<PluginRuntime>(s.host, s.services, s.actuators);
  if (cfg.runtime.r2r.is_object() && cfg.runtime.r2r.value("enabled", false)) s.services.r2r = &s.r2r_bridge;
  s.runtime->start_drivers(cfg);
  std::vector<DeadlineCrew::Job> halts;
  for (const auto& slot : s.actuators.slots())
    if (slot.driver != nullptr) halts.push_back({slot.id, [driver = slot.driver] { driver->halt(); }});
  s.halt_crew = std::make_unique<DeadlineCrew>("estop.halt", std::move(halts), [priority = cfg.runtime.stop_path_priority] {
    enter_stop_path_priority(priority);
  });
  s.estop.use_halt_crew(s.halt_crew.get());
  s.runtime->start_capabilities(s.registry->names(), cfg);
  s.estop.on_latched([runtime = s.runtime.get()] { runtime->notify_estop(); });
  // The latch record in runtime.state_dir follows every latch and clear (written off the stop path).
  s.estop.on_latched([&s] {
    if (auto* state = s.state_dir_live.load()) state->latch_changed();
  });
  s.estop.on_cleared([&s] {
    if (auto* state = s.state_dir_live.load()) state->latch_changed();
  });
  if (cfg.estop_on_startup) s.estop.latch("safety.estop_on_startup", "config");

  s.timers = std::make_unique<WorkerThread>("kernel.timers", nullptr);
  s.api_context.reset(new ApiContext{cfg, *s.auth, *s.registry, s.host, *s.runtime, s.estop, s.audit, s.clock, *s.timers,
                                     std::chrono::milliseconds(cfg.runtime.handler_timeout_ms), std::string(kRcandVersion),
                                     s.clock.now_us()});
  // §15: the swarm peers. No file means no peers (broadcasts reach this robot only); a malformed one stops startup.
  if (std::error_code ec; std::filesystem::exists(cfg.runtime.swarm_file, ec)) {
    try {
      s.swarm = swarm::load_swarm_file(cfg.runtime.swarm_file);
    } catch (const swarm::SwarmError& e) {
      throw StartupError(std::string("runtime.swarm_file: ") + e.what());
    }
    for (const auto& warning : s.swarm.warnings) log->warn("{}", warning);
    log->info("swarm: {} peer(s) from {}", s.swarm.nodes.size(), cfg.runtime.swarm_file.string());
  } else {
    log->info("swarm: no swarm file at {}; broadcasts reach this robot only", cfg.runtime.swarm_file.string());
  }
  // docs/protocol.md §9: "mDNS host first, the static ip when resolution fails": *.local peers resolve through avahi-daemon.
  std::vector<std::string> mdns_hosts;
  for (const auto& node : s.swarm.nodes)
    if (mdns::is_mdns_host(node.host)) mdns_hosts.push_back(node.host);
  if (!mdns_hosts.empty()) {
    s.mdns_resolver = std::make_shared<mdns::AvahiHostResolver>(logger("kernel.mdns"));
    s.mdns_resolver->start();
    s.mdns_resolver->prefetch(mdns_hosts);  // the first broadcast stop then finds them in the cache
  }
  s.fan_out = std::make_unique<swarm::FanOut>(s.mdns_resolver);
  s.api_context->swarm = &s.swarm;
  s.api_context->fan_out = s.fan_out.get();
  s.api = std::make_unique<Api>(*s.api_context);
  // docs/protocol.md §11: R2R, when runtime.r2r.enabled (its peers are swarm.yaml's as loaded now).
  s.r2r = R2rService::from_config({cfg, *s.auth, *s.api, s.estop, s.clock, s.swarm, ruri, s.registry->names()});
  s.api_context->r2r = s.r2r.get();
  if (s.r2r) s.r2r_bridge.attach(s.r2r->node());  // plugin subscriptions made while starting now receive
  if (cfg.enable_mdns) {
    s.mdns_publisher = std::make_unique<mdns::ServicePublisher>(logger("kernel.mdns"));
    // TXT "status" follows an e-stop at once, not at the next once-a-second check (never blocks the stop path).
    s.estop.on_latched([publisher = s.mdns_publisher.get()] { publisher->refresh_soon(); });
  }
}

Kernel::~Kernel() { shutdown(); }

std::uint16_t Kernel::start() {
  auto& s = *state_;
  // runtime.state_dir (one rcand per state dir): the e-stop starts latched when the last run ended without a clean
  // shutdown or while latched, with the reason in GET /api/estop and the audit log. Before anything is served.
  if (!s.state_dir) {
    try {
      s.state_dir = std::make_unique<StateDir>(s.config.runtime.state_dir);
    } catch (const std::runtime_error& e) {
      throw StartupError(e.what());
    }
    const auto& previous = s.state_dir->previous();
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
      if (s.estop.latched()) s.estop.restate(why + "; safety.estop_on_startup is set as well", "startup");
      else s.estop.latch(why, "startup");
      const auto now = s.clock.wall_ms();
      const auto seq = s.audit.record({0, "rcand", s.services.ruri, "startup-" + std::to_string(now), "e-stop latched at startup",
                                       now, "pending", {}});
      s.audit.finish(seq, "ok", why);
      logger("kernel.estop")->warn("starting latched: {}", why);
    }
    s.state_dir->start_writer([&s] {
      const auto now = s.estop.snapshot();
      return StateDir::LatchRecord{now.estopped, now.reason, now.source, now.since_ms};
    });
    s.state_dir_live.store(s.state_dir.get());
    s.state_dir->latch_changed();  // the record says what this run starts with
  }
  http::ServerOptions options;
  options.address = s.address;
  options.port = s.port;
  options.max_connections = connections_within_fd_limit(s.config.runtime.max_connections, options.busy_lane);
  options.max_connections_per_address = s.config.runtime.max_connections_per_address;
  // The e-stop is read and handled on the accept thread, ahead of any other work, and is answered even when every
  // connection slot is taken (issue 13: neither load nor a flood may delay or lock out a stop).
  options.on_thread_start = [priority = s.config.runtime.stop_path_priority](bool accept_loop) {
    if (accept_loop) enter_stop_path_priority(priority);
  };
  options.priority = [](const http::Request& request) {
    return (request.method == "POST" && request.path == "/api/stop") || (request.method == "GET" && request.path == "/api/estop");
  };
  if (s.r2r) options.upgrade = s.r2r->upgrade_handler();  // WS /ws/r2r on the robot's own port
  s.server = std::make_unique<http::Server>(options, [api = s.api.get()](http::Request&& request, http::Respond respond) {
    api->handle(std::move(request), std::move(respond));
  });
  try {
    s.port = s.server->start();
  } catch (const std::exception& e) {
    throw StartupError(e.what());
  }
  s.api_context->port = s.port;
  if (s.r2r) s.r2r->start(s.port);  // throws StartupError naming the runtime.r2r setting at fault
  if (s.mdns_publisher) {
    // docs/protocol.md §5: instance metadata.robot_name, the port bound, the TXT record of the one registry function (§9.5).
    s.mdns_publisher->start({.name = s.config.robot_name,
                             .type = std::string(kServiceType),
                             .port = s.port,
                             .txt = [&s] { return s.registry->advertise(s.api->robot_state(), s.port).txt; }});
  }
  logger("kernel")->info("{} ({}) serving RCAN {} on http://{}:{} with capabilities [{}]", s.config.robot_name,
                         s.registry->identity().ruri, kRcanVersion, s.address, s.port,
                         s.registry->advertise("idle", s.port).txt.at("caps"));
  return s.port;
}

void Kernel::shutdown() noexcept {
  if (!state_ || state_->shut_down) return;
  auto& s = *state_;
  s.shut_down = true;
  try {
    const auto before = s.estop.snapshot();          // what the state dir keeps: the latch as it was, not this one
    s.estop.latch("rcand shutting down", "kernel");  // motors stop first, whatever else happens
    if (s.r2r) s.r2r->stop();  // then no R2R message is handled or sent
    s.r2r_bridge.detach();      // plugins' links no longer reach the node
    if (s.mdns_publisher) s.mdns_publisher->stop();  // withdrawn (goodbye sent) while HTTP still answers
    if (s.server) s.server->stop();
    if (s.fan_out) s.fan_out->stop();  // broadcasts in flight are abandoned; their clients are gone
    if (s.mdns_resolver) s.mdns_resolver->stop();
    // A halt() still running (slow or hung driver) must not have its driver destroyed under it: leak the plugin
    // objects instead (the process is ending).
    const bool halts_quiet = !s.halt_crew || s.halt_crew->quiesce(std::chrono::seconds(2));
    if (s.runtime) s.runtime->shutdown();
    s.estop.use_halt_crew(nullptr);
    if (!halts_quiet) {
      logger("kernel")->error("a driver's halt() is still running at shutdown; its plugin objects are not destroyed");
      keep_forever(s.runtime);
    }
    if (s.timers) s.timers->join();
    // Last: a shutdown that does not get here (a crash, the grace timer) leaves the running marker.
    if (s.state_dir) {
      s.state_dir_live.store(nullptr);
      s.state_dir->clean_exit({before.estopped, before.reason, before.source, before.since_ms});
    }
  } catch (const std::exception& e) {
    logger("kernel")->error("during shutdown: {}", e.what());
  }
}

Kernel::ReloadReport Kernel::reload(const std::filesystem::path& file) noexcept {
  static const std::vector<std::string> kLiveKeys{"runtime.auth", "runtime.logging", "runtime.swarm_file"};
  auto& s = *state_;
  ReloadReport report;
  auto log = logger("kernel");
  std::optional<std::string> new_log_level;
  try {
    // Everything that can fail is read and checked before anything changes.
    LoadedConfig loaded = load_robot_config(file);
    const RobotConfig& next = loaded.config;
    AuthSettings auth = auth_settings(next, s.services.ruri, s.address);
    auto swarm = std::make_unique<swarm::SwarmRegistry>();
    if (std::error_code ec; std::filesystem::exists(next.runtime.swarm_file, ec)) {
      try {
        *swarm = swarm::load_swarm_file(next.runtime.swarm_file);
      } catch (const swarm::SwarmError& e) {
        throw StartupError(std::string("runtime.swarm_file: ") + e.what());
      }
    }
    s.auth->replace(std::move(auth));
    new_log_level = next.runtime.log_level;  // applied after this reload's own log line
    s.api_context->swarm = swarm.get();
    s.retired_swarms.push_back(std::move(swarm));  // requests in flight may still read the ones before
    for (const auto& warning : loaded.warnings) log->warn("{}", warning.format());
    for (auto& key : changed_keys(s.config.doc, next.doc)) {
      const bool live = std::any_of(kLiveKeys.begin(), kLiveKeys.end(), [&](const auto& p) { return key_is_under(key, p); });
      (live ? report.applied : report.needs_restart).push_back(std::move(key));
    }
    report.ok = true;
  } catch (const ConfigError& e) {
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
    const std::string detail =
        report.ok ? "applied: " + join(report.applied) + "; needs a restart: " + join(report.needs_restart)
                  : "invalid, still running on the previous config: " + join(report.errors);
    // docs/protocol.md §6.3: a config change is audited like a command (before the log line that announces it).
    const auto seq = s.audit.record({0, "SIGHUP", s.services.ruri, "reload-" + std::to_string(s.clock.wall_ms()),
                                     "config reload", s.clock.wall_ms(), "pending", {}});
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
