// sdk::Metrics across an isolated capability's channel. In the host, RemoteMetrics is the service the plugin finds: a
// call is checked against the SDK's rules there (its answer is the one rcand would give for the rules) and sent to
// rcand without waiting; rcand records it in its own metrics (record_remote_metric), which checks it again.
#pragma once

#include <nlohmann/json.hpp>

#include "libs/isolation/channel.hpp"
#include "rcand/sdk/interfaces/metrics.hpp"

namespace rcand::isolation {

class RemoteMetrics final : public sdk::Metrics {
 public:
  explicit RemoteMetrics(Channel& channel) : channel_(channel) {}
  bool record(const sdk::MetricFamily& family, std::span<const std::string_view> label_values, sdk::MetricOp op,
              double value) const noexcept override;

 private:
  Channel& channel_;
};

// rcand: a "metric" message of the host, into `metrics` (null: rcand offers none). Throws nlohmann's exception for a
// message that does not decode.
void record_remote_metric(const sdk::Metrics* metrics, const nlohmann::json& message);

}  // namespace rcand::isolation
