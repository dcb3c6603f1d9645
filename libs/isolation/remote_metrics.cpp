#include "libs/isolation/remote_metrics.hpp"

#include <string>
#include <vector>

#include "rcand/sdk/contract/metric_rules.hpp"

namespace rcand::isolation {

using nlohmann::json;

bool RemoteMetrics::record(const sdk::MetricFamily& family, std::span<const std::string_view> label_values, sdk::MetricOp op,
                           double value) const noexcept {
  if (!sdk::contract::metric_family_error(family).empty() ||
      !sdk::contract::metric_sample_error(family, label_values, op, value).empty())
    return false;
  try {
    json message{{"t", "metric"},
                 {"name", family.name},
                 {"type", static_cast<int>(family.type)},
                 {"help", family.help},
                 {"labels", std::vector<std::string>(family.labels.begin(), family.labels.end())},
                 {"buckets", std::vector<double>(family.buckets.begin(), family.buckets.end())},
                 {"values", std::vector<std::string>(label_values.begin(), label_values.end())},
                 {"op", static_cast<int>(op)},
                 {"value", value}};
    return channel_.send(message, nullptr, /*wait=*/false);
  } catch (...) {  // a label value that is not UTF-8
    return false;
  }
}

void record_remote_metric(const sdk::Metrics* metrics, const json& message) {
  if (metrics == nullptr) return;
  const auto name = message.at("name").get<std::string>(), help = message.at("help").get<std::string>();
  const auto labels = message.at("labels").get<std::vector<std::string>>();
  const auto buckets = message.at("buckets").get<std::vector<double>>();
  const auto values = message.at("values").get<std::vector<std::string>>();
  const std::vector<std::string_view> label_views(labels.begin(), labels.end()), value_views(values.begin(), values.end());
  const auto type = message.at("type").get<int>(), op = message.at("op").get<int>();
  if (type < 0 || type > static_cast<int>(sdk::MetricType::Histogram) || op < 0 || op > static_cast<int>(sdk::MetricOp::Observe))
    return;
  const sdk::MetricFamily family{name, static_cast<sdk::MetricType>(type), help, label_views, buckets};
  metrics->record(family, value_views, static_cast<sdk::MetricOp>(op), message.at("value").get<double>());
}

}  // namespace rcand::isolation
