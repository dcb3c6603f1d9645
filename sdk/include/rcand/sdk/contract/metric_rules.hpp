// The rules a metric family and its samples must keep (rcand/sdk/interfaces/metrics.hpp), written once and used by rcand's
// telemetry and by the fake host (testing/recording_metrics.hpp), so a plugin test that records a metric holds on the
// robot. They are the conventions `promtool check metrics` lints, so an accepted family never makes a finding.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <span>
#include <string>
#include <string_view>

#include "rcand/sdk/interfaces/metrics.hpp"

namespace rcand::sdk::contract {

inline constexpr std::size_t kMaxMetricNameBytes = 128;
inline constexpr std::size_t kMaxMetricHelpBytes = 300;
inline constexpr std::size_t kMaxMetricLabels = 8;
inline constexpr std::size_t kMaxMetricBuckets = 32;
inline constexpr std::size_t kMaxLabelValueBytes = 128;
inline constexpr std::size_t kMaxSeriesPerFamily = 500;  // label-value sets; beyond it new ones are refused
inline constexpr std::size_t kMaxMetricFamilies = 256;   // per robot, every plugin together

namespace detail {

inline bool is_snake_case(std::string_view name) {
  if (name.empty() || name.size() > kMaxMetricNameBytes || name.starts_with("__")) return false;
  if (name.front() >= '0' && name.front() <= '9') return false;
  for (char c : name)
    if (!((c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_')) return false;
  return true;
}

// Why one '_'-separated word of a name breaks the unit conventions, or empty.
inline std::string word_error(std::string_view word) {
  for (std::string_view abbreviation : {"s", "ms", "us", "ns", "sec", "b", "kb", "mb", "gb", "tb", "pb", "m", "h", "d"})
    if (word == abbreviation)
      return "abbreviated unit '" + std::string(word) + "': spell the base unit out (seconds, bytes, meters)";
  struct NonBase {
    std::string_view unit, base;
  };
  static constexpr NonBase kNonBase[] = {
      {"nanoseconds", "seconds"}, {"microseconds", "seconds"}, {"milliseconds", "seconds"}, {"minutes", "seconds"},
      {"hours", "seconds"},       {"days", "seconds"},         {"weeks", "seconds"},        {"bits", "bytes"},
      {"kilobytes", "bytes"},     {"megabytes", "bytes"},      {"gigabytes", "bytes"},      {"terabytes", "bytes"},
      {"millimeters", "meters"},  {"centimeters", "meters"},   {"kilometers", "meters"},    {"milligrams", "grams"},
      {"kilograms", "grams"},     {"millivolts", "volts"},     {"milliamperes", "amperes"}, {"fahrenheit", "celsius"}};
  for (const auto& n : kNonBase)
    if (word == n.unit) return "'" + std::string(n.unit) + "' is not a base unit: use " + std::string(n.base);
  for (std::string_view type : {"counter", "gauge", "histogram", "summary"})
    if (word == type) return "the type '" + std::string(type) + "' does not belong in the name";
  return {};
}

inline bool valid_utf8_line(std::string_view text) {
  for (std::size_t i = 0; i < text.size();) {
    const auto c = static_cast<unsigned char>(text[i]);
    if (c == '\n' || c == '\r') return false;
    const std::size_t n = c < 0x80 ? 1 : (c >> 5) == 0x6 ? 2 : (c >> 4) == 0xE ? 3 : (c >> 3) == 0x1E ? 4 : 0;
    if (n == 0 || i + n > text.size()) return false;
    for (std::size_t k = 1; k < n; ++k)
      if ((static_cast<unsigned char>(text[i + k]) & 0xC0) != 0x80) return false;
    i += n;
  }
  return true;
}

}  // namespace detail

// Why `family` cannot be declared, or empty.
inline std::string metric_family_error(const MetricFamily& family) {
  const std::string_view name = family.name;
  const std::string quoted = "'" + std::string(name.substr(0, kMaxMetricNameBytes)) + "'";
  if (!detail::is_snake_case(name))
    return "metric name " + quoted + " must be lowercase snake_case ([a-z_][a-z0-9_]*, at most 128 bytes, not '__...')";
  const bool counter = family.type == MetricType::Counter;
  if (counter && !name.ends_with("_total")) return "counter " + quoted + " must end in '_total'";
  if (!counter && name.ends_with("_total")) return "only a counter ends in '_total': " + quoted;
  for (std::string_view suffix : {"_count", "_sum", "_bucket"})
    if (name.ends_with(suffix)) return "metric name " + quoted + " must not end in '" + std::string(suffix) + "'";
  for (std::size_t start = 0; start <= name.size();) {
    const std::size_t end = std::min(name.find('_', start), name.size());
    if (auto why = detail::word_error(name.substr(start, end - start)); !why.empty()) return "metric name " + quoted + ": " + why;
    start = end + 1;
  }
  if (family.help.empty() || family.help.size() > kMaxMetricHelpBytes || !detail::valid_utf8_line(family.help))
    return "metric " + quoted + ": help must be one line of UTF-8, 1 to 300 bytes";
  if (family.labels.size() > kMaxMetricLabels) return "metric " + quoted + ": more than 8 labels";
  for (std::size_t i = 0; i < family.labels.size(); ++i) {
    const std::string_view label = family.labels[i];
    if (!detail::is_snake_case(label) || label.size() > 64)
      return "metric " + quoted + ": label name '" + std::string(label.substr(0, 64)) +
             "' must be lowercase snake_case, not '__...'";
    if (label == "le" || label == "quantile") return "metric " + quoted + ": label name '" + std::string(label) + "' is reserved";
    for (std::size_t j = 0; j < i; ++j)
      if (family.labels[j] == label) return "metric " + quoted + ": label '" + std::string(label) + "' given twice";
  }
  if (family.type != MetricType::Histogram && !family.buckets.empty())
    return "metric " + quoted + ": only a histogram has buckets";
  if (family.buckets.size() > kMaxMetricBuckets) return "metric " + quoted + ": more than 32 buckets";
  for (std::size_t i = 0; i < family.buckets.size(); ++i)
    if (!std::isfinite(family.buckets[i]) || (i > 0 && !(family.buckets[i] > family.buckets[i - 1])))
      return "metric " + quoted + ": buckets must be finite and strictly increasing";
  return {};
}

// The buckets a histogram family uses.
inline std::span<const double> metric_buckets(const MetricFamily& family) {
  return family.buckets.empty() ? std::span<const double>(kDefaultBuckets) : family.buckets;
}

// Why this sample of a valid `family` is refused, or empty.
inline std::string metric_sample_error(const MetricFamily& family, std::span<const std::string_view> label_values, MetricOp op,
                                       double value) {
  const std::string name(family.name);
  if (op == MetricOp::Declare) return {};
  if (label_values.size() != family.labels.size())
    return name + ": " + std::to_string(label_values.size()) + " label values for " + std::to_string(family.labels.size()) +
           " labels";
  if (std::isnan(value) || std::isinf(value)) return name + ": the value must be a finite number";
  switch (family.type) {
    case MetricType::Counter:
      if (op != MetricOp::Add) return name + ": a counter only adds";
      if (value < 0) return name + ": a counter never goes down (negative step)";
      return {};
    case MetricType::Gauge:
      if (op != MetricOp::Add && op != MetricOp::Set) return name + ": a gauge adds or sets";
      return {};
    case MetricType::Histogram:
      if (op != MetricOp::Observe) return name + ": a histogram observes";
      return {};
  }
  return name + ": unknown metric type";
}

// Whether two declarations of one name agree (help may differ: the first one's is kept).
inline bool same_metric_shape(const MetricFamily& a, const MetricFamily& b) {
  if (a.type != b.type || a.labels.size() != b.labels.size()) return false;
  for (std::size_t i = 0; i < a.labels.size(); ++i)
    if (a.labels[i] != b.labels[i]) return false;
  const auto ab = metric_buckets(a), bb = metric_buckets(b);
  if (a.type == MetricType::Histogram && !std::equal(ab.begin(), ab.end(), bb.begin(), bb.end())) return false;
  return true;
}

// A label value as exposed: invalid UTF-8 and control characters replaced by '?', cut to 128 bytes on a character.
inline std::string metric_label_value(std::string_view value) {
  std::string out;
  for (std::size_t i = 0; i < value.size();) {
    const auto c = static_cast<unsigned char>(value[i]);
    std::size_t n = c < 0x80 ? 1 : (c >> 5) == 0x6 ? 2 : (c >> 4) == 0xE ? 3 : (c >> 3) == 0x1E ? 4 : 0;
    bool ok = n > 0 && i + n <= value.size() && !(n == 1 && (c < 0x20 || c == 0x7F));
    for (std::size_t k = 1; ok && k < n; ++k) ok = (static_cast<unsigned char>(value[i + k]) & 0xC0) == 0x80;
    if (!ok) n = 1;
    if (out.size() + (ok ? n : 1) > kMaxLabelValueBytes) break;
    if (ok) out.append(value.substr(i, n));
    else out += '?';
    i += n;
  }
  return out;
}

}  // namespace rcand::sdk::contract
