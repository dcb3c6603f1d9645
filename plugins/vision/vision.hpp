// The vision capability (RCAN §9 vision, docs/protocol.md §7): one camera from the robot's `camera` block, served as
//   GET /api/stream/mjpeg     multipart/x-mixed-replace, one JPEG per part; ?fps= asks for fewer frames
//   GET /api/stream/snapshot  one image/jpeg
//   GET /api/depth/obstacles  the obstacle zones (docs/protocol.md §7.9), from the latest depth frame
//   GET /api/depth/frame      the latest depth frame, colour-mapped, as one image/jpeg
//   POST /api/depth/sim_obstacle  sim only (camera.depth: synthetic): places or removes an object in the scene
// With `camera.depth: synthetic` a synthetic depth scene feeds the zones, and the capability offers them as the robot's
// sdk::ObstacleSource (rcand/sdk/services.hpp), which nav and teleop find. The stream and frame routes are stream routes
// (rcand/sdk/stream.hpp, SDK ABI 1.2): handlers only register the viewer and return; the camera's capture thread and the hub's
// delivery thread do the rest. Request threads never touch the camera.
#pragma once

#include <rcand/sdk/plugin.hpp>
#include <rcand/sdk/stream.hpp>

#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include "capture.hpp"
#include "depth.hpp"
#include "frame_hub.hpp"

namespace rcand::plugins::vision {

struct VisionSettings {
  SourceSettings source;
  HubOptions hub;
  CaptureOptions capture;
  DepthSettings depth;
  int jpeg_quality = 80;
};

// The RCAN `camera` block (type, device, url, path, resolution or width/height, fps or framerate, fourcc) and
// rcand's own settings (runtime.capabilities.vision, defaults from the manifest). Throws sdk::ConfigError naming
// the key at fault. A camera block without a type is a V4L2 device (/dev/video0 unless `device` says otherwise):
// never the synthetic source, which only `type: synthetic` selects.
VisionSettings read_settings(const sdk::ConfigView& camera, const sdk::ConfigView& own);

// ?fps=: a number in (0, 120], or nullopt with `error` set.
std::optional<double> parse_fps(std::string_view text, std::string& error);

class Vision final : public sdk::Capability {
 public:
  static constexpr double kMaxFps = 120.0;
  // At least a frame every 5 s: a viewer offered no frame for 10 s is cut (rcand/sdk/stream.hpp), so anything slower
  // would only hold a viewer's place for a while; it is refused (400) instead.
  static constexpr double kMinFps = 0.2;

  // `encoder` and `sources` replace the JPEG encoder and the source made from the config (tests).
  explicit Vision(sdk::PluginContext& ctx, Encoder encoder = {}, SourceFactory sources = {});
  ~Vision() override;

  void start() override;
  std::vector<sdk::Route> routes() override;
  std::vector<sdk::StreamRoute> stream_routes() override;
  sdk::Json status() const override { return hub_->status(); }
  void shutdown() noexcept override;

  FrameHub& hub() noexcept { return *hub_; }
  DepthFeed* depth() noexcept { return depth_.get(); }  // null without camera.depth
  const VisionSettings& settings() const noexcept { return settings_; }

 private:
  void mjpeg(const sdk::Request& request, const std::shared_ptr<sdk::StreamWriter>& writer);
  void snapshot(const sdk::Request& request, const std::shared_ptr<sdk::StreamWriter>& writer);
  sdk::Response obstacles(const sdk::Request& request) const;
  sdk::Response sim_obstacle(const sdk::Request& request);
  void depth_frame(const sdk::Request& request, const std::shared_ptr<sdk::StreamWriter>& writer) const;

  sdk::PluginContext& ctx_;
  VisionSettings settings_;
  SourceFactory sources_;
  std::shared_ptr<FrameHub> hub_;
  std::unique_ptr<Capture> capture_;
  std::unique_ptr<DepthFeed> depth_;  // offered as the ObstacleSource: lives as long as the instance
};

}  // namespace rcand::plugins::vision
