// The camera stream as Prometheus metrics (rcand/sdk/interfaces/metrics.hpp), taken from the status the frame hub publishes (on
// every change, and about once a second while someone watches), so the delivery thread does nothing more per frame:
//   rcand_vision_stream_viewers                    MJPEG viewers watching now
//   rcand_vision_frames_per_second{stage}          captured (from the camera) and encoded (JPEG, sent to viewers)
// Nothing is recorded when nothing offers sdk::Metrics.
#pragma once

#include <rcand/sdk/context.hpp>

namespace rcand::plugins::vision {

void declare_stream_metrics(const sdk::PluginContext& ctx) noexcept;
// One status of the frame hub (FrameHub::status()).
void record_stream_metrics(const sdk::PluginContext& ctx, const sdk::Json& hub_status) noexcept;

}  // namespace rcand::plugins::vision
