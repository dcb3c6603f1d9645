#include "rcand/kernel/core/kernel.hpp"

#include <boost/asio/ip/address.hpp>

#include "rcand/kernel/auth/authenticator.hpp"
#include "rcand/kernel/auth/ruri.hpp"
#include "rcand/kernel/auth/secret_file.hpp"
#include "rcand/kernel/core/actuator_table.hpp"
#include "rcand/kernel/core/api.hpp"
#include "rcand/kernel/core/audit_log.hpp"
#include "rcand/kernel/core/estop.hpp"
#include "rcand/kernel/core/kernel_motion_gate.hpp"
#include "rcand/kernel/core/logging.hpp"
#include "rcand/kernel/core/plugin_runtime.hpp"
#include "rcand/kernel/core/steady_clock.hpp"
#include "rcand/kernel/http/server.hpp"
#include "rcand/kernel/swarm/fan_out.hpp"
#include "rcand/kernel/swarm/swarm_registry.hpp"

namespace rcand::kernel {
namespace {

bool is_loopback(const std::string& address) {
  boost::system::error_code ec;
  const auto parsed = boost::asio::ip::make_address(address, ec);
  return !ec && parsed.is_loopback();
}

AuthSettings auth_settings(const RobotConfig& config, const std::string& ruri, const std::string& address) {
  AuthSettings settings;
  settings.robot_ruri = ruri;
  if (const auto parsed = parse_ruri(ruri).ruri) settings.device_id = parsed->device_id;
  const auto& auth = config.runtime.auth;
  if (auth.mode == "open") {
    // notes §3 ruling: no-auth mode exists only on loopback.
    if (!is_loopback(address))
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
  std::unique_ptr<Authenticator> auth;
  std::unique_ptr<CapabilityRegistry> registry;
  std::unique_ptr<PluginRuntime> runtime;
  std::unique_ptr<WorkerThread> timers;
  std::unique_ptr<ApiContext> api_context;
  std::unique_ptr<Api> api;
  std::unique_ptr<http::Server> server;
  swarm::SwarmRegistry swarm;
  std::unique_ptr<swarm::FanOut> fan_out;  // declared after the Api's context: stopped and destroyed before it
  bool shut_down = false;
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
  s.host.load_needed(capabilities, protocols);
  for (const auto& record : s.host.records())
    if (is_failure(record->state))
      log->error("plugin {} ({}): {} — {}{}", record->id, record->manifest_file.string(), to_string(record->state),
                 record->reason, record->hint.empty() ? "" : " (hint: " + record->hint + ")");

  s.registry = std::make_unique<CapabilityRegistry>(RobotIdentity{ruri, cfg.robot_name, cfg.model}, std::move(plan));
  s.runtime = std::make_unique<PluginRuntime>(s.host, s.services, s.actuators);
  s.runtime->start_drivers(cfg);
  s.runtime->start_capabilities(s.registry->names(), cfg);
  s.estop.on_latched([runtime = s.runtime.get()] { runtime->notify_estop(); });
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
  s.fan_out = std::make_unique<swarm::FanOut>();
  s.api_context->swarm = &s.swarm;
  s.api_context->fan_out = s.fan_out.get();
  s.api = std::make_unique<Api>(*s.api_context);
}

Kernel::~Kernel() { shutdown(); }

std::uint16_t Kernel::start() {
  auto& s = *state_;
  http::ServerOptions options;
  options.address = s.address;
  options.port = s.port;
  s.server = std::make_unique<http::Server>(options, [api = s.api.get()](http::Request&& request, http::Respond respond) {
    api->handle(std::move(request), std::move(respond));
  });
  try {
    s.port = s.server->start();
  } catch (const std::exception& e) {
    throw StartupError(e.what());
  }
  s.api_context->port = s.port;
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
    s.estop.latch("rcand shutting down", "kernel");  // motors stop first, whatever else happens
    if (s.server) s.server->stop();
    if (s.fan_out) s.fan_out->stop();  // broadcasts in flight are abandoned; their clients are gone
    if (s.runtime) s.runtime->shutdown();
    if (s.timers) s.timers->join();
  } catch (const std::exception& e) {
    logger("kernel")->error("during shutdown: {}", e.what());
  }
}

const PluginHost& Kernel::plugins() const noexcept { return state_->host; }
const CapabilityRegistry& Kernel::registry() const noexcept { return *state_->registry; }
Api& Kernel::api() noexcept { return *state_->api; }

}  // namespace rcand::kernel
