// The metrics plugins and rcand's in-tree services contribute (rcand/sdk/interfaces/metrics.hpp): the telemetry service offers
// this object as sdk::Metrics and writes its families into GET /metrics after its own. A call checks the rules
// (rcand/sdk/contract/metric_rules.hpp), looks its family and label values up and changes one number, under one
// brief lock; a scrape writes every family under the same lock. Refusals are counted and logged once per family and
// reason, so a plugin calling wrongly on every frame cannot flood the log.
#pragma once

#include <rcand/sdk/interfaces/metrics.hpp>

#include <atomic>
#include <cstdint>
#include <deque>
#include <map>
#include <mutex>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "services/telemetry/metrics_text.hpp"

namespace rcand::services::telemetry {

class PluginMetrics final : public sdk::Metrics {
 public:
  // `reserved`: the family names rcand writes itself; a contributed family of one of these names is refused.
  explicit PluginMetrics(std::vector<std::string> reserved);

  bool record(const sdk::MetricFamily& family, std::span<const std::string_view> label_values, sdk::MetricOp op,
              double value) const noexcept override;
  // Every family, HELP and TYPE once each, in the order they were declared.
  void write(MetricsText& out) const;
  // Calls refused so far.
  std::uint64_t refused() const noexcept { return refused_.load(std::memory_order_relaxed); }

 private:
  struct Series {
    double value = 0.0;                  // counter, gauge
    std::vector<std::uint64_t> buckets;  // histogram: observations <= each bound (not cumulative)
    std::uint64_t count = 0;
    double sum = 0.0;
  };
  struct Family {
    std::string name, help;
    sdk::MetricType type;
    std::vector<std::string> labels;
    std::vector<double> bounds;
    std::map<std::vector<std::string>, Series> series;
  };
  bool matches(const Family& known, const sdk::MetricFamily& family) const;
  bool refuse(const std::string& why) const noexcept;  // under mutex_

  const std::set<std::string, std::less<>> reserved_;
  mutable std::mutex mutex_;
  mutable std::deque<Family> families_;  // declaration order; never moves an element
  mutable std::map<std::string, Family*, std::less<>> by_name_;
  mutable std::set<std::string> logged_;  // "family: reason" already logged
  mutable std::atomic<std::uint64_t> refused_{0};
};

}  // namespace rcand::services::telemetry
