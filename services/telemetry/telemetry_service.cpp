#include "services/telemetry/telemetry_service.hpp"

#include <atomic>

#include "kernel/kernel.hpp"
#include "kernel/safety/stop_summary.hpp"
#include "libs/config/config_schema.hpp"
#include "libs/http/server.hpp"
#include "rcand/sdk/interfaces/obstacle_source.hpp"
#include "services/telemetry/metrics_text.hpp"
#include "services/telemetry/plugin_metrics.hpp"
#include "services/telemetry/route_metrics.hpp"
#include "services/telemetry/status_metrics.hpp"
#include "services/telemetry/stop_metrics.hpp"
#include "services/telemetry/telemetry_frame.hpp"
#include "services/telemetry/telemetry_hub.hpp"

namespace rcand::services {
namespace {

using nlohmann::json;
using namespace rcand::services::telemetry;

// runtime.telemetry: this service's keys, joined to the config's one table (libs/config/config_schema.hpp).
// clang-format off
const config::ConfigFragment kTelemetryKeys({
    {.path = "runtime.telemetry", .type = config::ValueType::Mapping, .description = "WS /ws/telemetry and GET /metrics"},
    {.path = "runtime.telemetry.metrics_port", .type = config::ValueType::Integer, .min = 1, .max = 65535,
     .description = "also serve GET /metrics without credentials on 127.0.0.1 at this port (loopback only: a local "
                    "Prometheus or node agent scrapes it; the robot's own port keeps asking for scope status)"},
    {.path = "runtime.telemetry.max_clients", .type = config::ValueType::Integer, .default_value = 256, .min = 1,
     .max = 100000, .description = "WS /ws/telemetry clients at once; beyond it the upgrade answers 503"},
    {.path = "runtime.telemetry.reserved_clients", .type = config::ValueType::Integer, .default_value = 32, .min = 0,
     .max = 100000, .description = "of max_clients, the last ones only OWNER and CREATOR get (503 SLOTS_RESERVED to others)"},
    {.path = "runtime.telemetry.max_clients_per_principal", .type = config::ValueType::Integer, .default_value = 8, .min = 1,
     .max = 100000, .description = "WS /ws/telemetry clients one principal below OWNER may hold; beyond it 429 TOO_MANY_CONNECTIONS"},
    {.path = "runtime.telemetry.max_clients_per_address", .type = config::ValueType::Integer, .default_value = 16, .min = 1,
     .max = 100000, .description = "WS /ws/telemetry clients the principals below OWNER may hold from one client address "
                                   "(everyone in auth mode open); beyond it 429 TOO_MANY_CONNECTIONS"},
});
// clang-format on

std::optional<std::int64_t> telemetry_setting(const json& doc, const char* key) {
  const json* at = &doc;
  for (const char* part : {"runtime", "telemetry", key}) {
    if (!at->is_object() || !at->contains(part)) return std::nullopt;
    at = &(*at)[part];
  }
  return at->is_number_integer() ? std::optional(at->get<std::int64_t>()) : std::nullopt;
}

// What the e-stop listeners touch: shared with them, so it outlives the service whatever the order of teardown.
struct EstopWatch {
  std::atomic<bool> latched{false};
  std::atomic<std::uint64_t> latches{0};  // not latched -> latched, as the listeners saw it
  std::weak_ptr<TelemetryHub> hub;
};

class TelemetryService final : public kernel::Service {
 public:
  explicit TelemetryService(kernel::ServiceHost& host) : host_(host) {
    HubOptions options;
    auto size_setting = [&host](const char* key, std::size_t fallback) {
      return static_cast<std::size_t>(telemetry_setting(host.config.doc, key).value_or(static_cast<std::int64_t>(fallback)));
    };
    options.max_clients = size_setting("max_clients", options.max_clients);
    options.reserved_clients = size_setting("reserved_clients", options.reserved_clients);
    options.max_clients_per_principal = size_setting("max_clients_per_principal", options.max_clients_per_principal);
    options.max_clients_per_address = size_setting("max_clients_per_address", options.max_clients_per_address);
    metrics_port_ = telemetry_setting(host.config.doc, "metrics_port");
    hub_ = std::make_shared<TelemetryHub>(options, host.auth, host.api,
                                          [this](std::uint64_t seq, std::string_view event) { return build_frame(seq, event); });
    watch_->hub = hub_;
    watch_->latched = host.estop.latched();
    // On the stop path, after the halt: an exchange, an add and a wake-up; the frame is built on the ticker.
    host.estop.on_latched([watch = watch_] {
      if (!watch->latched.exchange(true)) watch->latches.fetch_add(1);
      if (auto hub = watch->hub.lock()) hub->signal(HubEvent::Latched);
    });
    // Runs under the e-stop's own lock: only flags.
    host.estop.on_cleared([watch = watch_] {
      watch->latched.store(false);
      if (auto hub = watch->hub.lock()) hub->signal(HubEvent::Cleared);
    });
    // Before the plugins start: they (and the other services) find sdk::Metrics at use time.
    MetricsText own;
    write_own_families(own, json::object());
    contributed_ = std::make_unique<PluginMetrics>(own.family_names());
    host.plugin_services.offer_service(sdk::Metrics::kServiceId, static_cast<const sdk::Metrics*>(contributed_.get()), this,
                                       "telemetry", nullptr);
  }
  ~TelemetryService() override {
    host_.plugin_services.withdraw(this);
    stop();
  }

  std::string_view name() const noexcept override { return "telemetry"; }

  void add_routes(kernel::Router& router) override {
    router.add({"GET", "/metrics", sdk::Scope::Status},
               [this](kernel::Call&, kernel::Reply reply) { reply(metrics_response()); });
    routes_.instrument(router);
    stops_.instrument(router);
  }

  http::UpgradeHandler upgrade() override { return hub_->upgrade_handler(); }

  void start(std::uint16_t) override {
    hub_->start();
    if (!metrics_port_) return;
    http::ServerOptions options;
    options.address = "127.0.0.1";
    options.port = static_cast<std::uint16_t>(*metrics_port_);
    options.io_threads = 1;
    options.screen = [api = &host_.api](const http::Request& request) { return api->screen(request); };
    metrics_server_ = std::make_unique<http::Server>(options, [this](http::Request&& request, http::Respond respond) {
      if (request.path != "/metrics") return respond(http::error_response(404, "NOT_FOUND", "only GET /metrics is served here"));
      if (request.method != "GET") return respond(http::error_response(405, "METHOD_NOT_ALLOWED", "GET /metrics only"));
      respond(metrics_response());
    });
    try {
      metrics_server_->start();
    } catch (const std::exception& e) {
      throw kernel::StartupError(std::string("runtime.telemetry.metrics_port: ") + e.what());
    }
  }

  void stop() noexcept override {
    if (metrics_server_) metrics_server_->stop();
    hub_->stop();
  }

 private:
  std::string build_frame(std::uint64_t seq, std::string_view event) const {
    FrameContext context;
    context.ts_ms = host_.clock.wall_ms();
    context.seq = seq;
    context.event = event;
    if (const auto estop = host_.estop.snapshot(); estop.estopped) {
      context.estop = kernel::estop_document(estop);  // GET /api/estop's fields: who, how, and the summary
      context.estop.erase("estopped");
    }
    context.obstacles = obstacles_field(sdk::find<sdk::ObstacleSource>(host_.plugin_services));
    return telemetry_frame(host_.status_document(), context).dump(-1, ' ', false, json::error_handler_t::replace);
  }

  http::Response metrics_response() const {
    MetricsText out;
    write_own_families(out, host_.status_document());
    contributed_->write(out);
    http::Response response;
    response.content_type = std::string(MetricsText::kContentType);
    response.body = out.text();
    return response;
  }

  // Every family rcand writes itself (the status snapshot's, the stops', the hub's, the routes').
  void write_own_families(MetricsText& out, const json& status) const {
    write_status_metrics(out, status);
    out.family("rcand_estop_latches_total", "counter", "times the e-stop went from clear to latched");
    out.sample(static_cast<double>(watch_->latches.load()));
    out.family("rcand_estop_stop_requests_total", "counter",
               "stop requests of any source, repeated stops while latched included");
    out.sample(static_cast<double>(host_.estop.epoch()));
    stops_.write(out);
    out.family("rcand_nav_jobs_accepted_total", "counter", "nav jobs accepted (POST /api/nav/waypoint answered 2xx)");
    out.sample(static_cast<double>(routes_.successes("POST", "/api/nav/waypoint")));
    write_hub_metrics(out, hub_->counters());
    routes_.write(out);
    out.family("rcand_metrics_refused_total", "counter",
               "metric calls of plugins and services refused (a bad name or label, a mismatched family; see the log)");
    out.sample(contributed_ ? static_cast<double>(contributed_->refused()) : 0.0);
  }

  static void write_hub_metrics(MetricsText& out, const HubCounters& c) {
    auto counter = [&out](const char* name, const char* help, std::uint64_t value) {
      out.family(name, "counter", help);
      out.sample(static_cast<double>(value));
    };
    out.family("rcand_telemetry_clients", "gauge", "WS /ws/telemetry clients connected");
    out.sample(static_cast<double>(c.clients));
    counter("rcand_telemetry_connections_total", "WS /ws/telemetry upgrades accepted", c.accepted);
    counter("rcand_telemetry_refused_total", "WS /ws/telemetry upgrades refused (401, 403, 429, 503)", c.refused);
    counter("rcand_telemetry_frames_built_total", "telemetry frames built (one per tick or push, shared by every client)",
            c.frames_built);
    counter("rcand_telemetry_frames_sent_total", "telemetry frames written to clients", c.frames_sent);
    counter("rcand_telemetry_frames_replaced_total",
            "frames a client skipped because a newer one replaced it while it read slowly", c.frames_replaced);
    out.family("rcand_telemetry_clients_dropped_total", "counter", "telemetry clients closed by rcand, by reason");
    out.sample({{"reason", "slow"}}, static_cast<double>(c.dropped_slow));
    out.sample({{"reason", "credential"}}, static_cast<double>(c.closed_credential));
    counter("rcand_telemetry_stops_total", "stops requested by telemetry clients ({\"cmd\":\"stop\"})", c.stops);
    counter("rcand_telemetry_bad_messages_total", "telemetry client messages answered with an error", c.bad_messages);
  }

  kernel::ServiceHost& host_;
  std::optional<std::int64_t> metrics_port_;
  std::shared_ptr<EstopWatch> watch_ = std::make_shared<EstopWatch>();
  std::shared_ptr<TelemetryHub> hub_;
  RouteMetrics routes_;
  StopMetrics stops_;
  std::unique_ptr<PluginMetrics> contributed_;  // offered as sdk::Metrics
  std::unique_ptr<http::Server> metrics_server_;
};

}  // namespace

std::unique_ptr<kernel::Service> make_telemetry(kernel::ServiceHost& host) { return std::make_unique<TelemetryService>(host); }

}  // namespace rcand::services
