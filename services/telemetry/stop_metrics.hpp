// What the stops' own answers report: latch -> every actuator halted ("latency_us") and each driver's halt
// ("drivers"[].latency_us, "halted"), read from the body POST /api/stop answers (an HTTP stop and a telemetry
// client's {"cmd":"stop"}, which goes through that same row). Stops that bypass the row (a plugin's request_estop,
// nav's obstacle stop, shutdown) are counted by the e-stop listeners (rcand_estop_latches_total) but report no
// latency here. Parsed after the answer was handed to the client, so the stop is never slower for it.
#pragma once

#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>

#include "kernel/api/router.hpp"
#include "services/telemetry/latency_histogram.hpp"
#include "services/telemetry/metrics_text.hpp"

namespace rcand::services::telemetry {

class StopMetrics {
 public:
  // Startup only: wraps POST /api/stop.
  void instrument(kernel::Router& router);
  // One stop answer's body (JSON); anything unreadable is ignored.
  void observe(std::string_view body);
  void write(MetricsText& out) const;

 private:
  struct Driver {
    LatencyHistogram halt{kHaltBounds};
    std::uint64_t failures = 0;  // halted: false (slow, hung or throwing)
  };
  LatencyHistogram latch_to_halted_{kHaltBounds};
  mutable std::mutex mutex_;  // drivers_ (written once per stop, read once per scrape)
  std::map<std::string, std::unique_ptr<Driver>, std::less<>> drivers_;
};

}  // namespace rcand::services::telemetry
