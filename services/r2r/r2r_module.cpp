#include "services/r2r/r2r_module.hpp"

#include "rcand/sdk/fleet_auctions.hpp"
#include "services/r2r/plugin_bridge.hpp"
#include "services/r2r/r2r_metrics.hpp"
#include "services/r2r/r2r_routes.hpp"
#include "services/r2r/r2r_service.hpp"

namespace rcand::services {
namespace {

using namespace rcand::kernel;

// The plugins' links reach the node through the bridge, which outlives them: the kernel destroys its services
// after the plugin instances.
class BridgeLinks final : public R2rLinkFactory {
 public:
  explicit BridgeLinks(r2r::PluginBridge& bridge) : bridge_(bridge) {}
  std::unique_ptr<sdk::R2rLink> make_link(sdk::Worker& worker, std::string who) override {
    return bridge_.make_link(worker, std::move(who));
  }

 private:
  r2r::PluginBridge& bridge_;
};

class R2rModule final : public Service {
 public:
  explicit R2rModule(ServiceHost& host) : host_(host), bridge_(fleet_lookup(host)) {
    service_ = R2rService::from_config(
        {host.config, host.auth,
         [api = &host.api](const Principal& principal, nlohmann::json body, std::function<void(int, nlohmann::json)> done) {
           api->execute_action(principal, std::move(body), std::move(done));
         },
         host.status_document, host.estop, host.clock, host.swarm_now, host.registry.identity().ruri, host.registry.names(),
         fleet_lookup(host), stop_lane(host)});
    if (!service_) return;
    bridge_.attach(service_->node());
    service_->node().observe_messages(r2r::message_metrics(host.plugin_services));
    host.offer_r2r_links(&links_);
  }
  ~R2rModule() override { stop(); }

  std::string_view name() const noexcept override { return "r2r"; }
  void add_routes(Router& router) override { add_r2r_routes(router, service_.get(), host_.audit); }
  http::UpgradeHandler upgrade() override { return service_ ? service_->upgrade_handler() : http::UpgradeHandler{}; }
  void start(std::uint16_t http_port) override {
    if (!service_) return;
    service_->start(http_port);  // throws StartupError naming the runtime.r2r setting at fault
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
  r2r::PluginBridge bridge_;  // before service_: destroyed after it
  BridgeLinks links_{bridge_};
  std::unique_ptr<R2rService> service_;
};

}  // namespace

std::unique_ptr<Service> make_r2r(ServiceHost& host) { return std::make_unique<R2rModule>(host); }

}  // namespace rcand::services
