#include "services/r2r/r2r_metrics.hpp"

#include <rcand/sdk/interfaces/metrics.hpp>

#include <array>
#include <string_view>

namespace rcand::services::r2r {

using namespace rcand::kernel;
namespace {

constexpr std::array<std::string_view, 3> kLabels{"direction", "type", "transport"};
constexpr sdk::MetricFamily kMessages{"rcand_r2r_messages_total", sdk::MetricType::Counter,
                                      "R2R messages accepted from and taken by each transport, by message type", kLabels};

}  // namespace

R2rNode::MessageObserver message_metrics(const ServiceDirectory& directory) {
  if (const auto* metrics = sdk::find<sdk::Metrics>(directory)) metrics->declare(kMessages);
  return [&directory](bool sent, r2r_wire::MessageType type, const std::string& transport) {
    if (const auto* metrics = sdk::find<sdk::Metrics>(directory))
      metrics->add(kMessages, {sent ? "sent" : "received", type_name(type), transport});
  };
}

}  // namespace rcand::services::r2r
