#include "services/r2r/r2r_module.hpp"

#include "libs/base/logging.hpp"
#include "rcand/sdk/interfaces/fleet_auctions.hpp"
#include "rcand/sdk/r2r.hpp"
#include "services/r2r/plugin_bridge.hpp"
#include "services/r2r/r2r_metrics.hpp"
#include "services/r2r/r2r_routes.hpp"
#include "services/r2r/r2r_service.hpp"

namespace rcand::services {
namespace {

using namespace rcand::kernel;

// Plugins' R2R links (sdk::R2rLinks, offered to the plugins' service directory) reach the node through the bridge,
// which outlives them: the kernel destroys its services after the plugin instances.
class BridgeLinks final : public sdk::R2rLinks {
 public:
  explicit BridgeLinks(r2r::PluginBridge& bridge) : bridge_(bridge) {}
  std::unique_ptr<sdk::R2rLink> make_link(sdk::Worker& worker, std::string_view who) const noexcept override {
    try {
      return bridge_.make_link(worker, std::string(who));
    } catch (const std::exception& e) {
      logger("kernel.r2r")->error("no R2R link for {}: {}", who, e.what());
      return nullptr;
    }
  }

 private:
  r2r::PluginBridge& bridge_;
};

class R2rModule final : public Service {
 public:
  R2rModule(ServiceHost& host, std::shared_ptr<const swarm::LiveRegistry> swarm)
      : host_(host), swarm_(std::move(swarm)), bridge_(fleet_lookup(host)) {
    service_ = r2r::R2rService::from_config(
        {host.config, host.auth,
         [api = &host.api](const Principal& principal, nlohmann::json body, std::function<void(int, nlohmann::json)> done) {
           api->execute_action(principal, std::move(body), std::move(done));
         },
         host.robot_state, [directory = &host.plugin_services] { return sdk::find<sdk::PoseSource>(*directory); }, host.estop,
         host.clock, [swarm = swarm_] { return &swarm->now(); }, host.registry.identity().ruri, host.registry.names(),
         fleet_lookup(host), stop_lane(host)});
    if (!service_) return;
    bridge_.attach(service_->node());
    service_->node().observe_messages(r2r::message_metrics(host.plugin_services));
    host.plugin_services.offer_service(sdk::R2rLinks::kServiceId, static_cast<const sdk::R2rLinks*>(&links_), this, "r2r",
                                       nullptr);
  }
  ~R2rModule() override {
    stop();
    host_.plugin_services.withdraw(this);
  }

  std::string_view name() const noexcept override { return "r2r"; }
  void add_routes(Router& router) override { add_r2r_routes(router, service_.get(), host_.audit); }
  http::UpgradeHandler upgrade() override { return service_ ? service_->upgrade_handler() : http::UpgradeHandler{}; }
  void start(std::uint16_t http_port) override {
    if (!service_) return;
    service_->start(http_port);  // throws StartupError naming the runtime.r2r setting at fault
  }
  // The peers file is read again; its key (a different file) needs a restart.
  ServiceReload prepare_reload(const config::RobotConfig&) override {
    if (!service_) return {};
    return {[service = service_.get()] { service->reload_peers(); }, {}};
  }
  // A price set before the fleet plugin offered its service (or before it was reloaded) reaches it now.
  void capabilities_changed() noexcept override { bridge_.sync_cost(true); }
  void stop() noexcept override {
    if (service_) service_->stop();  // no R2R message is handled or sent after this
    bridge_.detach();                // plugins' links no longer reach the node
  }

 private:
  // The fleet plugin's auctions, looked up at each use: plugins start after this service is made, and may fail.
  static r2r::PluginBridge::FleetLookup fleet_lookup(ServiceHost& host) {
    return [directory = &host.plugin_services] { return sdk::find<sdk::FleetAuctions>(*directory); };
  }

  // The fleet e-stop's way to the latch: POST /api/stop itself, run inline as the R2R sender (Api::execute answers on
  // the calling thread: the route's audit entry, then Estop::latch), so it never waits behind a command's worker.
  static r2r::StopExecutor stop_lane(ServiceHost& host) {
    return [api = &host.api, clock = &host.clock](const Principal& principal, nlohmann::json body) {
      http::Request request;
      request.method = "POST";
      request.target = request.path = "/api/stop";
      request.body = body.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
      request.remote = "r2r";
      request.headers["x-message-id"] = "r2r-estop-" + std::to_string(clock->wall_ms());
      api->execute(principal, std::move(request), [](http::Response) {});
    };
  }

  ServiceHost& host_;
  std::shared_ptr<const swarm::LiveRegistry> swarm_;  // swarm.yaml as now: whom a relay or a WebSocket dial reaches
  r2r::PluginBridge bridge_;                          // before service_: destroyed after it
  BridgeLinks links_{bridge_};
  std::unique_ptr<r2r::R2rService> service_;
};

}  // namespace

std::unique_ptr<Service> make_r2r(ServiceHost& host, std::shared_ptr<const swarm::LiveRegistry> swarm) {
  return std::make_unique<R2rModule>(host, std::move(swarm));
}

}  // namespace rcand::services
