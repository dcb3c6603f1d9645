#include "services/telemetry/plugin_metrics.hpp"

#include <rcand/sdk/contract/metric_rules.hpp>

#include <algorithm>

#include "libs/base/logging.hpp"

namespace rcand::services::telemetry {
namespace {

std::string_view type_name(sdk::MetricType type) {
  switch (type) {
    case sdk::MetricType::Counter: return "counter";
    case sdk::MetricType::Gauge: return "gauge";
    case sdk::MetricType::Histogram: return "histogram";
  }
  return "untyped";
}

constexpr std::size_t kMaxLoggedRefusals = 1000;  // distinct reasons; beyond it refusals are only counted

}  // namespace

PluginMetrics::PluginMetrics(std::vector<std::string> reserved) : reserved_(reserved.begin(), reserved.end()) {}

bool PluginMetrics::matches(const Family& known, const sdk::MetricFamily& family) const {
  if (known.type != family.type ||
      !std::equal(known.labels.begin(), known.labels.end(), family.labels.begin(), family.labels.end()))
    return false;
  const auto bounds = sdk::contract::metric_buckets(family);
  return family.type != sdk::MetricType::Histogram ||
         std::equal(known.bounds.begin(), known.bounds.end(), bounds.begin(), bounds.end());
}

// Under mutex_.
bool PluginMetrics::refuse(const std::string& why) const noexcept {
  refused_.fetch_add(1, std::memory_order_relaxed);
  try {
    if (logged_.size() < kMaxLoggedRefusals && logged_.insert(why).second)
      logger("telemetry.metrics")->warn("metric refused (logged once): {}", why);
  } catch (...) {  // no memory to log: still refused
  }
  return false;
}

bool PluginMetrics::record(const sdk::MetricFamily& family, std::span<const std::string_view> label_values, sdk::MetricOp op,
                           double value) const noexcept {
  try {
    std::lock_guard lock(mutex_);
    auto known = by_name_.find(family.name);
    if (known == by_name_.end()) {
      if (auto why = sdk::contract::metric_family_error(family); !why.empty()) return refuse(why);
      if (reserved_.contains(family.name)) return refuse("metric name '" + std::string(family.name) + "' is rcand's own");
      if (families_.size() >= sdk::contract::kMaxMetricFamilies)
        return refuse("metric '" + std::string(family.name) + "': already 256 families");
      Family& added = families_.emplace_back();
      added.name = family.name;
      added.help = family.help;
      added.type = family.type;
      added.labels.assign(family.labels.begin(), family.labels.end());
      if (family.type == sdk::MetricType::Histogram) {
        const auto bounds = sdk::contract::metric_buckets(family);
        added.bounds.assign(bounds.begin(), bounds.end());
      }
      known = by_name_.emplace(added.name, &added).first;
    } else if (!matches(*known->second, family)) {
      return refuse("metric '" + std::string(family.name) + "' declared again with another type, labels or buckets");
    }
    if (auto why = sdk::contract::metric_sample_error(family, label_values, op, value); !why.empty()) return refuse(why);
    if (op == sdk::MetricOp::Declare) return true;

    Family& f = *known->second;
    std::vector<std::string> key;
    key.reserve(label_values.size());
    for (const auto v : label_values) key.push_back(sdk::contract::metric_label_value(v));
    auto series = f.series.find(key);
    if (series == f.series.end()) {
      if (f.series.size() >= sdk::contract::kMaxSeriesPerFamily)
        return refuse("metric '" + f.name + "': more than 500 label sets (a label that should not be one?)");
      series = f.series.emplace(std::move(key), Series{}).first;
      series->second.buckets.assign(f.bounds.size(), 0);
    }
    Series& s = series->second;
    switch (op) {
      case sdk::MetricOp::Add: s.value += value; break;
      case sdk::MetricOp::Set: s.value = value; break;
      case sdk::MetricOp::Observe: {
        const auto bucket = std::lower_bound(f.bounds.begin(), f.bounds.end(), value);  // first bound >= value
        if (bucket != f.bounds.end()) ++s.buckets[static_cast<std::size_t>(bucket - f.bounds.begin())];
        ++s.count;
        s.sum += value;
        break;
      }
      case sdk::MetricOp::Declare: break;
    }
    return true;
  } catch (...) {  // no memory: this sample is lost, nothing else
    refused_.fetch_add(1, std::memory_order_relaxed);
    return false;
  }
}

void PluginMetrics::write(MetricsText& out) const {
  std::lock_guard lock(mutex_);
  for (const Family& f : families_) {
    out.family(f.name, type_name(f.type), f.help);
    for (const auto& [values, s] : f.series) {
      Labels labels;
      for (std::size_t i = 0; i < f.labels.size() && i < values.size(); ++i) labels.emplace_back(f.labels[i], values[i]);
      if (f.type != sdk::MetricType::Histogram) {
        out.sample(labels, s.value);
        continue;
      }
      HistogramSample h;
      h.bounds = f.bounds;
      std::uint64_t running = 0;
      for (const auto n : s.buckets) h.cumulative.push_back(running += n);
      h.count = s.count;
      h.sum = s.sum;
      out.histogram(labels, h);
    }
  }
}

}  // namespace rcand::services::telemetry
