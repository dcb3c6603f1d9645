// A Metrics service (rcand/sdk/interfaces/metrics.hpp) that keeps what a plugin recorded, for tests on the fake host. It refuses
// exactly what rcand refuses (the same rules, rcand/sdk/contract/metric_rules.hpp):
//
//   rcand::sdk::testing::RecordingMetrics metrics;
//   rcand::sdk::offer<rcand::sdk::Metrics>(host, metrics);       // before the instance that records starts
//   ... exercise the plugin ...
//   CHECK(metrics.value("acme_camera_grabs_total", {"front", "ok"}) == 1);
//   CHECK(metrics.refusals().empty());                           // every call kept the rules
#pragma once

#include <map>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

#include "rcand/sdk/contract/metric_rules.hpp"
#include "rcand/sdk/interfaces/metrics.hpp"

namespace rcand::sdk::testing {

class RecordingMetrics final : public Metrics {
 public:
  bool record(const MetricFamily& family, std::span<const std::string_view> label_values, MetricOp op,
              double value) const noexcept override {
    try {
      std::lock_guard lock(mutex_);
      std::string why = contract::metric_family_error(family);
      auto known = families_.find(family.name);
      if (why.empty() && known != families_.end() && !contract::same_metric_shape(known->second.shape, family))
        why = std::string(family.name) + ": declared before with another type, labels or buckets";
      if (why.empty()) why = contract::metric_sample_error(family, label_values, op, value);
      if (!why.empty()) {
        refusals_.push_back(std::move(why));
        return false;
      }
      if (known == families_.end()) known = families_.emplace(std::string(family.name), Family{family, {}}).first;
      if (op == MetricOp::Declare) return true;
      std::vector<std::string> key;
      for (const auto v : label_values) key.push_back(contract::metric_label_value(v));
      Series& series = known->second.series[key];
      if (op == MetricOp::Set) series.value = value;
      else if (op == MetricOp::Add) series.value += value;
      else series.observations.push_back(value);
      return true;
    } catch (...) {
      return false;
    }
  }

  // A counter's or gauge's value for these label values (0 when never recorded).
  double value(std::string_view family, const std::vector<std::string>& label_values = {}) const {
    std::lock_guard lock(mutex_);
    const Series* s = find(family, label_values);
    return s ? s->value : 0.0;
  }
  // A histogram's observations for these label values, in order.
  std::vector<double> observations(std::string_view family, const std::vector<std::string>& label_values = {}) const {
    std::lock_guard lock(mutex_);
    const Series* s = find(family, label_values);
    return s ? s->observations : std::vector<double>{};
  }
  bool declared(std::string_view family) const {
    std::lock_guard lock(mutex_);
    return families_.find(family) != families_.end();
  }
  // Why each refused call was refused, in order (rcand logs these).
  std::vector<std::string> refusals() const {
    std::lock_guard lock(mutex_);
    return refusals_;
  }

 private:
  struct Series {
    double value = 0.0;
    std::vector<double> observations;
  };
  struct Family {
    MetricFamily shape;  // its spans point at the plugin's constants
    std::map<std::vector<std::string>, Series> series;
  };
  const Series* find(std::string_view family, const std::vector<std::string>& label_values) const {
    const auto f = families_.find(family);
    if (f == families_.end()) return nullptr;
    const auto s = f->second.series.find(label_values);
    return s == f->second.series.end() ? nullptr : &s->second;
  }

  mutable std::mutex mutex_;
  mutable std::map<std::string, Family, std::less<>> families_;
  mutable std::vector<std::string> refusals_;
};

}  // namespace rcand::sdk::testing
