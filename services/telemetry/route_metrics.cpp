#include "services/telemetry/route_metrics.hpp"

#include <chrono>
#include <set>
#include <utility>

namespace rcand::services::telemetry {

void RouteMetrics::instrument(kernel::Router& router) {
  instrument_new_rows(router);
  router.on_group_replaced([this, &router] { instrument_new_rows(router); });
}

void RouteMetrics::instrument_new_rows(kernel::Router& router) {
  // Collected first: wrapping a row while walking the table would match against rows being changed.
  std::vector<std::pair<std::string, std::string>> targets;
  std::set<std::pair<const kernel::Route*, std::string>> seen;
  const auto table = router.routes();
  std::lock_guard lock(mutex_);
  for (const auto& route : table->routes) {
    const auto& spec = route.spec;
    std::vector<std::string> methods;
    if (spec.method == "*") methods = {"GET", "POST", "PUT", "PATCH", "DELETE"};
    else methods = {spec.method};
    for (auto& method : methods) {
      // A "*" row's method may be served by a more specific row of the same path: wrap each row once per method.
      const kernel::Route* serving = router.match(method, spec.path).route;
      if (serving != &route || !seen.emplace(serving, method).second) continue;
      if (instrumented_.emplace(method, spec.path).second) targets.emplace_back(std::move(method), spec.path);
    }
  }
  for (auto& [method, path] : targets) {
    Row* row = &rows_.emplace_back(method, path);
    router.wrap(method, path, [row](kernel::Call& call, kernel::Reply reply, const kernel::RouteHandler& next) {
      const auto started = std::chrono::steady_clock::now();
      next(call, [row, started, reply = std::move(reply)](http::Response response) {
        row->latency.observe(std::chrono::steady_clock::now() - started);
        row->by_status.add(response.status);
        reply(std::move(response));
      });
    });
  }
}

void RouteMetrics::write(MetricsText& out) const {
  std::lock_guard lock(mutex_);
  out.family("rcand_http_requests_total", "counter",
             "HTTP requests answered by each route (after authentication and rate limits), by status code");
  for (const Row& row : rows_)
    row.by_status.for_each([&](int code, std::uint64_t n) {
      out.sample({{"method", row.method}, {"route", row.path}, {"code", code == 0 ? "other" : std::to_string(code)}},
                 static_cast<double>(n));
    });
  out.family("rcand_http_request_duration_seconds", "histogram",
             "time from the route's handler being called to its answer, per route");
  for (const Row& row : rows_) out.histogram({{"method", row.method}, {"route", row.path}}, row.latency.read());
}

std::uint64_t RouteMetrics::successes(std::string_view method, std::string_view path) const {
  std::lock_guard lock(mutex_);
  std::uint64_t total = 0;
  for (const Row& row : rows_)
    if (row.method == method && row.path == path)
      row.by_status.for_each([&](int code, std::uint64_t n) {
        if (code >= 200 && code < 300) total += n;
      });
  return total;
}

}  // namespace rcand::services::telemetry
