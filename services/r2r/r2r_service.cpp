#include "services/r2r/r2r_service.hpp"

#include <boost/asio/ip/address.hpp>

#include <algorithm>
#include <mutex>
#include <stdexcept>

#include "kernel/kernel.hpp"
#include "libs/base/logging.hpp"
#include "libs/base/worker_thread.hpp"
#include "libs/rcan/loopback.hpp"
#include "services/r2r/r2r_settings.hpp"
#include "services/r2r/transports/mqtt_transport.hpp"
#include "services/r2r/transports/udp_transport.hpp"
#include "services/r2r/transports/websocket_transport.hpp"

namespace rcand::services::r2r {

using namespace rcand::kernel;

// Named, not anonymous: R2rService::Impl (external linkage) keeps these.
namespace r2r_service_detail {

// One forwarded auction request: answered once, by the fleet plugin or by stop(), whichever comes first.
class PendingAnswer {
 public:
  explicit PendingAnswer(std::function<void(const sdk::Response&)> done) : done_(std::move(done)) {}
  void answer(const sdk::Response& response) {
    std::function<void(const sdk::Response&)> done;
    {
      std::lock_guard lock(mutex_);
      done.swap(done_);
    }
    if (done) done(response);
  }
  bool answered() {
    std::lock_guard lock(mutex_);
    return !done_;
  }

 private:
  std::mutex mutex_;
  std::function<void(const sdk::Response&)> done_;
};

}  // namespace r2r_service_detail

using r2r_service_detail::PendingAnswer;

namespace {

using nlohmann::json;

// The node's clock work runs this often: a changed status (a latch from HTTP, a pose) goes out within a tick, and no
// more often than every 200 ms anyway (the node's kMinStatusGapUs); a fleet e-stop's latched status goes at once.
// At 20 ms the ticks alone cost an idle robot ~0.5 % of a core (a fleet of 200: a whole core).
constexpr std::chrono::milliseconds kTickPeriod{100};

sdk::Response shutting_down() { return sdk::Response::error(503, "UNAVAILABLE", "rcand is shutting down"); }

}  // namespace

struct R2rService::Impl {
  explicit Impl(R2rServiceDeps d) : deps(std::move(d)) {}

  R2rServiceDeps deps;
  std::shared_ptr<spdlog::logger> log = logger("kernel.r2r");
  std::unique_ptr<r2r::WebSocketTransport> ws;
  std::unique_ptr<r2r::MqttTransport> mqtt;
  std::unique_ptr<r2r::UdpTransport> udp;
  bool udp_enabled = true;
  std::optional<std::uint16_t> udp_port;
  std::string udp_bind;
  std::vector<r2r::UdpDestination> udp_destinations;
  std::unique_ptr<r2r::R2rNode> node;
  r2r::R2rSettings peers_source;  // runtime.r2r.peers_file and the inline peers, for a reload

  std::mutex mutex;  // below
  bool started = false, stopping = false;
  std::vector<std::shared_ptr<PendingAnswer>> pending;  // auction requests the fleet plugin has not answered yet
  std::unique_ptr<WorkerThread> ticker;                 // "r2r.clock": one tick every kTickPeriod, from start() to stop()

  // What `status` reports: the robot's state and the e-stop latch as now, nav's dead-reckoned pose (a robot without
  // nav stays where its runtime.r2r.origin puts it) and the tasks the fleet plugin holds. Cheap enough for every
  // tick: no copy of the status document (a moving robot's clock once spent most of its time copying it).
  r2r::LocalStatus local_status() {
    r2r::LocalStatus status;
    status.estopped = deps.estop.latched();
    status.state = status.estopped ? "estop" : deps.robot_state();
    if (status.state == "estop" && !status.estopped) status.state = "idle";  // the state was read just before a clear
    if (const sdk::PoseSource* source = deps.pose ? deps.pose() : nullptr) {
      if (const sdk::PoseReading reading = source->read(); reading.available) status.pose = reading.pose;
    } else if (std::find(deps.capabilities.begin(), deps.capabilities.end(), "nav") == deps.capabilities.end()) {
      status.pose = sdk::Pose2d{};
    }
    if (const sdk::FleetAuctions* fleet = deps.fleet ? deps.fleet() : nullptr) status.tasks_held = fleet->tasks_held();
    return status;
  }

  // One tick, then the next one kTickPeriod later, until stop().
  void tick() {
    try {
      node->tick();
    } catch (const std::exception& e) {
      log->error("r2r clock: {}", e.what());
    } catch (...) {
      log->error("r2r clock: a non-standard exception");
    }
    std::lock_guard lock(mutex);
    if (!stopping) ticker->schedule(kTickPeriod, [this] { tick(); });
  }
};

std::unique_ptr<R2rService> R2rService::from_config(R2rServiceDeps deps) {
  const config::RobotConfig& cfg = deps.config;
  const json& r2r_block = cfg.runtime.r2r;
  if (!r2r_block.is_object() || !r2r_block.contains("enabled") || r2r_block["enabled"] != true) return nullptr;
  auto impl = std::make_unique<Impl>(std::move(deps));
  Impl& s = *impl;
  const std::filesystem::path base_dir =
      cfg.source_file.empty() ? std::filesystem::current_path() : cfg.source_file.parent_path();
  r2r::R2rSettings settings;
  try {
    settings = r2r::load_r2r_settings(r2r_block, base_dir);
  } catch (const std::invalid_argument& e) {
    throw StartupError(e.what());
  }
  for (const auto& warning : settings.warnings) s.log->warn("{}", warning);
  s.peers_source = settings;

  const bool has_mqtt = r2r_block.contains("mqtt") && r2r_block["mqtt"].is_object();
  const bool ws_dial = r2r_block.contains("ws_dial") ? r2r_block["ws_dial"] == true : !has_mqtt;
  r2r::WebSocketOptions ws_options;
  ws_options.self_name = cfg.robot_name;
  if (ws_dial) ws_options.dial_peers = s.deps.swarm;
  ws_options.log = s.log;
  r2r::apply_websocket_config(r2r_block, ws_options);  // slot caps, reserved slots, send queue (issue 13 #12, #15)
  s.ws = std::make_unique<r2r::WebSocketTransport>(ws_options, s.deps.authenticator);

  if (has_mqtt) {
    try {
      auto mqtt_options = r2r::mqtt_options_from_config(r2r_block["mqtt"], cfg.robot_name, base_dir);
      mqtt_options.log = s.log;
      s.mqtt = std::make_unique<r2r::MqttTransport>(std::move(mqtt_options));
    } catch (const std::invalid_argument& e) {
      throw StartupError(e.what());
    }
  }

  s.udp_enabled = r2r_block.value("udp_enabled", true);
  if (r2r_block.contains("udp_port")) s.udp_port = r2r_block["udp_port"].get<std::uint16_t>();
  // A socket bound to one unicast address never sees broadcasts: any address, unless the robot is loopback-only.
  s.udp_bind =
      r2r_block.value("udp_bind", is_loopback_address(cfg.runtime.listen_address) ? cfg.runtime.listen_address : "0.0.0.0");
  // No implicit destination (issue 13 #10): status datagrams go only where the operator says (udp_broadcast).
  const json destinations = r2r_block.contains("udp_broadcast") ? r2r_block["udp_broadcast"] : json::array();
  for (std::size_t i = 0; i < destinations.size(); ++i) {
    try {
      s.udp_destinations.push_back(
          r2r::parse_udp_destination(destinations[i].get<std::string>(), "runtime.r2r.udp_broadcast[" + std::to_string(i) + "]"));
    } catch (const std::invalid_argument& e) {
      throw StartupError(e.what());
    }
  }

  r2r::R2rNodeDeps node_deps{
      .identity = {cfg.robot_name, s.deps.ruri, s.deps.capabilities},
      .clock = s.deps.clock,
      .authenticator = s.deps.authenticator,
      .settings = std::move(settings),
      .status_source = [impl = &s] { return impl->local_status(); },
      .command_executor = [execute = s.deps.execute_action](
                              const Principal& principal, json body,
                              r2r::CommandDone done) { execute(principal, std::move(body), std::move(done)); },
      .transports = {s.ws.get()},
      .fleet_member =
          [swarm = s.deps.swarm](const std::string& id) {
            const swarm::SwarmRegistry* registry = swarm();
            return registry != nullptr && registry->find(id) != nullptr;
          },
      .log = s.log,
      .stop_executor = s.deps.execute_stop,
      // On the clock thread (it runs at background priority, and is joined before the node stops), or inline before
      // it runs or once it stopped.
      .after_stop =
          [impl = &s](std::function<void()> work) {
            std::unique_lock lock(impl->mutex);
            if (impl->ticker && !impl->stopping) return impl->ticker->post(std::move(work));
            lock.unlock();
            work();
          },
  };
  if (s.mqtt) node_deps.transports.push_back(s.mqtt.get());
  // UDP and MQTT never carry the bearer token (header.auth.token goes only over WebSocket): without a signing key,
  // what this robot sends over them is unauthenticated and peers that require credentials refuse it.
  if (node_deps.settings.outbound_token && !node_deps.settings.private_key && (s.mqtt || s.udp_enabled))
    s.log->warn(
        "r2r: runtime.r2r.token_file is sent over WebSocket only, never over {}; set runtime.r2r.private_key_file "
        "so peers can authenticate those messages (signed)",
        s.mqtt && s.udp_enabled ? "UDP or MQTT"
        : s.mqtt                ? "MQTT"
                                : "UDP");
  if (s.udp_enabled && s.udp_destinations.empty())
    s.log->warn(
        "r2r: runtime.r2r.udp_broadcast is not set: status is not sent over UDP (received only); name the "
        "destinations, e.g. udp_broadcast: [\"192.168.1.255\"]");
  s.node = std::make_unique<r2r::R2rNode>(std::move(node_deps));
  return std::unique_ptr<R2rService>(new R2rService(std::move(impl)));
}

R2rService::R2rService(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

R2rService::~R2rService() { stop(); }

http::UpgradeHandler R2rService::upgrade_handler() { return impl_->ws->upgrade_handler(); }

void R2rService::start(std::uint16_t http_port) {
  Impl& s = *impl_;
  const auto& cfg = s.deps.config;
  if (s.udp_enabled) {
    r2r::UdpOptions options;
    options.bind_address = s.udp_bind;
    options.port = s.udp_port.value_or(cfg.rcan_port);
    options.destinations = s.udp_destinations;
    options.log = s.log;
    s.udp = std::make_unique<r2r::UdpTransport>(std::move(options));
    s.node->add_transport(s.udp.get());
  }
  try {
    s.node->start();
  } catch (const std::exception& e) {
    s.node->stop();
    throw StartupError(e.what());
  }
  {
    std::lock_guard lock(s.mutex);
    s.started = true;
    s.ticker = std::make_unique<WorkerThread>("r2r.clock", nullptr, WorkerThread::Priority::Background);
    s.ticker->post([&s] { s.tick(); });
  }
  s.log->info("r2r: {} speaks R2R on ws://{}:{}{}{}{}", cfg.robot_name, cfg.runtime.listen_address, http_port,
              r2r::kWebSocketPath, s.udp ? ", udp " + std::to_string(s.udp->bound_port()) : std::string(),
              s.mqtt ? ", mqtt" : "");
}

void R2rService::stop() noexcept {
  Impl& s = *impl_;
  std::vector<std::shared_ptr<PendingAnswer>> abandoned;
  {
    std::lock_guard lock(s.mutex);
    if (s.stopping) return;
    s.stopping = true;
    abandoned.swap(s.pending);
  }
  if (s.ticker) s.ticker->join();  // a tick under way ends, and schedules no other once `stopping` is set
  s.node->stop();
  for (auto& request : abandoned) {
    try {
      request->answer(shutting_down());
    } catch (...) {
    }
  }
}

r2r::R2rNode& R2rService::node() noexcept { return *impl_->node; }

void R2rService::reload_peers() noexcept {
  Impl& s = *impl_;
  if (!s.peers_source.peers_file) return;
  try {
    auto peers = r2r::reload_peers(s.peers_source);
    const std::size_t count = peers.size();
    s.node->replace_peers(std::move(peers));
    s.log->info("r2r: peers file {} reloaded: {} peers accepted", s.peers_source.peers_file->string(), count);
  } catch (const std::exception& e) {
    s.log->error("r2r: peers file not reloaded, the previous peers stay in force: {}", e.what());
  }
}

const sdk::FleetAuctions* R2rService::fleet() const { return impl_->deps.fleet ? impl_->deps.fleet() : nullptr; }

json R2rService::peers() const {
  const Impl& s = *impl_;
  json doc = s.node->peers();
  doc["name"] = s.deps.config.robot_name;
  json transports = {{"ws", s.ws->connections()}};
  if (s.mqtt) transports["mqtt"] = {{"connected", s.mqtt->connected()}};
  if (s.udp) {
    json destinations = json::array();
    for (const auto& destination : s.udp_destinations)
      destinations.push_back(!destination.port ? destination.host
                             : destination.host.find(':') != std::string::npos
                                 ? "[" + destination.host + "]:" + std::to_string(destination.port)
                                 : destination.host + ":" + std::to_string(destination.port));
    transports["udp"] = {{"port", s.udp->bound_port()}, {"destinations", std::move(destinations)}};
  }
  doc["transports"] = std::move(transports);
  const auto counters = s.node->counters();
  doc["counters"] = {{"received", counters.received}, {"accepted", counters.accepted},       {"rejected", counters.rejected},
                     {"sent", counters.sent},         {"send_failed", counters.send_failed}, {"relayed", counters.relayed}};
  const sdk::FleetAuctions* auctions = fleet();
  doc["held_tasks"] = auctions != nullptr ? auctions->held_tasks() : json::array();
  return doc;
}

void R2rService::request_auction(const sdk::FleetAuctions& fleet, const json& body,
                                 std::function<void(const sdk::Response&)> done) {
  Impl& s = *impl_;
  auto request = std::make_shared<PendingAnswer>(std::move(done));
  bool stopping = false;
  {
    std::lock_guard lock(s.mutex);
    stopping = s.stopping;
    if (!stopping) {
      std::erase_if(s.pending, [](const auto& earlier) { return earlier->answered(); });
      s.pending.push_back(request);
    }
  }
  if (stopping) return request->answer(shutting_down());
  fleet.open(body, [request](const sdk::Response& response) { request->answer(response); });
}

}  // namespace rcand::services::r2r
