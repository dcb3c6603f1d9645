#include "stream_metrics.hpp"

#include <rcand/sdk/interfaces/metrics.hpp>

#include <array>
#include <string_view>

namespace rcand::plugins::vision {
namespace {

constexpr sdk::MetricFamily kViewers{
    "rcand_vision_stream_viewers", sdk::MetricType::Gauge, "MJPEG viewers of the camera stream now (GET /api/stream/mjpeg)", {}};
constexpr std::array<std::string_view, 1> kStageLabel{"stage"};
constexpr sdk::MetricFamily kFps{
    "rcand_vision_frames_per_second", sdk::MetricType::Gauge,
    "camera frames per second: captured; encoded for viewers, or passed_through (a camera's own JPEG sent as it is; "
    "0 while nobody watches)",
    kStageLabel};

double number(const sdk::Json& doc, const char* key) {
  const auto it = doc.find(key);
  return it != doc.end() && it->is_number() ? it->get<double>() : 0.0;
}

}  // namespace

void declare_stream_metrics(const sdk::PluginContext& ctx) noexcept {
  if (const auto* metrics = sdk::find<sdk::Metrics>(ctx)) {
    metrics->set(kViewers, 0);
    metrics->declare(kFps);
  }
}

void record_stream_metrics(const sdk::PluginContext& ctx, const sdk::Json& hub_status) noexcept {
  const auto* metrics = sdk::find<sdk::Metrics>(ctx);
  if (metrics == nullptr || !hub_status.is_object()) return;
  const auto viewers = hub_status.find("viewers");
  metrics->set(kViewers, viewers != hub_status.end() && viewers->is_array() ? static_cast<double>(viewers->size()) : 0.0);
  metrics->set(kFps, {"captured"}, number(hub_status, "captured_fps"));
  metrics->set(kFps, {"encoded"}, number(hub_status, "encoded_fps"));
  metrics->set(kFps, {"passed_through"}, number(hub_status, "passed_through_fps"));
}

}  // namespace rcand::plugins::vision
