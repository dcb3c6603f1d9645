// Prometheus metrics a plugin contributes to rcand's GET /metrics, as a service (rcand/sdk/services.hpp): rcand's
// telemetry offers it, a plugin finds it at use time and records samples.
//
//   constexpr std::array<std::string_view, 2> kLabels{"camera", "outcome"};
//   constexpr rcand::sdk::MetricFamily kGrabs{"acme_camera_grabs_total", rcand::sdk::MetricType::Counter,
//                                              "frames grabbed, by outcome", kLabels};
//   if (const auto* metrics = rcand::sdk::find<rcand::sdk::Metrics>(ctx_)) metrics->add(kGrabs, {"front", "ok"});
//
// A family is known by its name. The first call that names it declares it (declare() does so without a sample, so it
// shows in GET /metrics before anything happened); later calls must give the same type, label names and buckets.
// Names follow Prometheus conventions, checked by the rules in rcand/sdk/contract/metric_rules.hpp (shared with the
// fake host): lowercase snake_case, a counter ends in "_total" and nothing else does, base units spelled out
// ("_seconds", "_bytes", "_meters"; not "_ms", not "_milliseconds"). Whatever breaks a rule - a bad name or label, a
// family redeclared with another shape, a negative counter step, a family or label set beyond the limits below - is
// refused: the call returns false and rcand logs it (once per family and reason); the exposition stays valid.
//
// Calls: any thread, thread-safe, noexcept, never block beyond a brief lock. Record on the events themselves (a
// call answered, a frame sent), not on a timer. Label values are free text (UTF-8, cut to 128 bytes); keep their set
// small - a label per robot-side thing (a provider, a camera, an outcome), never a request id or a timestamp.
#pragma once

#include <cstddef>
#include <cstdint>
#include <initializer_list>
#include <span>
#include <string_view>

#include "rcand/sdk/export.hpp"
#include "rcand/sdk/services.hpp"

namespace rcand::sdk {

enum class MetricType : std::uint8_t { Counter, Gauge, Histogram };

// A family's fixed description: usually a constexpr at namespace scope (the spans must outlive every call).
struct MetricFamily {
  std::string_view name = {};  // "rcand_chat_brain_calls_total"
  MetricType type = MetricType::Counter;
  std::string_view help = {};                     // one line, required
  std::span<const std::string_view> labels = {};  // label names; values are given in this order
  std::span<const double> buckets = {};           // histogram: upper bounds, finite, increasing; empty: kDefaultBuckets
};

// Prometheus' usual latency buckets, in seconds.
inline constexpr double kDefaultBuckets[] = {0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1, 2.5, 5, 10};

enum class MetricOp : std::uint8_t {
  Declare,  // the family only (no sample)
  Add,      // counter: += value (>= 0); gauge: += value (either sign)
  Set,      // gauge: = value
  Observe,  // histogram: one observation of value
};

class RCAND_INTERFACE Metrics {
 public:
  static constexpr std::string_view kServiceId = "rcand.metrics/1";
  virtual ~Metrics() = default;

  // The one call an implementation provides. `label_values`: one per family.labels, in order (for Declare: none).
  // Returns false when refused (see above). Any thread, brief lock at most, never throws.
  virtual bool record(const MetricFamily& family, std::span<const std::string_view> label_values, MetricOp op,
                      double value) const noexcept = 0;

  // The usual calls, as record().
  bool declare(const MetricFamily& family) const noexcept { return record(family, {}, MetricOp::Declare, 0); }
  bool add(const MetricFamily& family, std::initializer_list<std::string_view> labels = {}, double amount = 1) const noexcept {
    return record(family, std::span(labels.begin(), labels.size()), MetricOp::Add, amount);
  }
  bool set(const MetricFamily& family, std::initializer_list<std::string_view> labels, double value) const noexcept {
    return record(family, std::span(labels.begin(), labels.size()), MetricOp::Set, value);
  }
  bool set(const MetricFamily& family, double value) const noexcept { return record(family, {}, MetricOp::Set, value); }
  bool observe(const MetricFamily& family, std::initializer_list<std::string_view> labels, double value) const noexcept {
    return record(family, std::span(labels.begin(), labels.size()), MetricOp::Observe, value);
  }
};

}  // namespace rcand::sdk
