// HTTP requests per route: a count per status code and a latency histogram, recorded by a decorator on every row
// of the route table (Router::wrap), so no kernel hook is needed. The clock starts when the decorator runs, which
// is after route matching, authentication and the rate limits, and stops when the row answers: requests refused
// before that (401, 403, 404, 405, 429) are not counted here, and the time excludes reading and writing the bytes.
// Recording is a few relaxed atomic adds (no lock on the request path).
#pragma once

#include <cstdint>
#include <deque>
#include <mutex>
#include <set>
#include <string>
#include <string_view>

#include "kernel/api/router.hpp"
#include "services/telemetry/latency_histogram.hpp"
#include "services/telemetry/metrics_text.hpp"
#include "services/telemetry/status_counts.hpp"

namespace rcand::services::telemetry {

class RouteMetrics {
 public:
  // Wraps each row present now (a "*" row once per common method), and each row a capability installs once it is up
  // (Router::on_group_replaced). Telemetry is last in linked_services() so that every service's rows are in. The
  // router must outlive this object's use by it (the kernel stops its capability starter before services go).
  void instrument(kernel::Router& router);
  // rcand_http_requests_total and rcand_http_request_duration_seconds.
  void write(MetricsText& out) const;
  // Answers 200..299 of one row (its pattern as added, e.g. "POST", "/api/nav/waypoint"); 0 when not instrumented.
  std::uint64_t successes(std::string_view method, std::string_view path) const;

 private:
  struct Row {
    Row(std::string m, std::string p) : method(std::move(m)), path(std::move(p)) {}
    std::string method, path;
    LatencyHistogram latency{kRequestBounds};
    StatusCounts by_status;
  };
  void instrument_new_rows(kernel::Router& router);

  mutable std::mutex mutex_;  // rows_ and instrumented_ (appended to while serving, as capabilities come up)
  std::deque<Row> rows_;      // never moves an element: decorators hold their row's address
  std::set<std::pair<std::string, std::string>> instrumented_;  // (method, path) wrapped already: wraps outlive swaps
};

}  // namespace rcand::services::telemetry
