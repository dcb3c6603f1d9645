#include "services/telemetry/stop_metrics.hpp"

#include <chrono>

#include <nlohmann/json.hpp>

namespace rcand::services::telemetry {

void StopMetrics::instrument(kernel::Router& router) {
  router.wrap("POST", "/api/stop", [this](kernel::Call& call, kernel::Reply reply, const kernel::RouteHandler& next) {
    next(call, [this, reply = std::move(reply)](http::Response response) {
      std::string body = response.status == 200 ? response.body : std::string();
      reply(std::move(response));  // the client first
      if (!body.empty()) observe(body);
    });
  });
}

void StopMetrics::observe(std::string_view body) {
  const auto doc = nlohmann::json::parse(body, nullptr, false);
  if (!doc.is_object()) return;
  using std::chrono::microseconds;
  if (const auto it = doc.find("latency_us"); it != doc.end() && it->is_number_integer())
    latch_to_halted_.observe(microseconds(it->get<std::int64_t>()));
  const auto drivers = doc.find("drivers");
  if (drivers == doc.end() || !drivers->is_array()) return;
  std::lock_guard lock(mutex_);
  for (const auto& entry : *drivers) {
    if (!entry.is_object() || !entry.contains("id") || !entry["id"].is_string()) continue;
    auto& driver = drivers_[entry["id"].get<std::string>()];
    if (!driver) driver = std::make_unique<Driver>();
    if (entry.contains("halted") && entry["halted"] == false) ++driver->failures;
    else if (const auto latency = entry.find("latency_us"); latency != entry.end() && latency->is_number_integer())
      driver->halt.observe(microseconds(latency->get<std::int64_t>()));
  }
}

void StopMetrics::write(MetricsText& out) const {
  out.family("rcand_estop_halt_latency_seconds", "histogram",
             "from entering the latch to every actuator confirmed halted, per stop answered by POST /api/stop");
  out.histogram({}, latch_to_halted_.read());
  std::lock_guard lock(mutex_);
  out.family("rcand_driver_halt_latency_seconds", "histogram", "one driver's halt() during a stop, per driver");
  for (const auto& [id, driver] : drivers_) out.histogram({{"driver", id}}, driver->halt.read());
  out.family("rcand_driver_halt_failures_total", "counter",
             "stops in which a driver's halt() did not confirm in time (slow, hung or threw), per driver");
  for (const auto& [id, driver] : drivers_) out.sample({{"driver", id}}, static_cast<double>(driver->failures));
}

}  // namespace rcand::services::telemetry
