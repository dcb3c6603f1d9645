// Depth obstacle zones (RCAN §12, docs/protocol.md §7.9): the nearest obstacle in the left, centre and right thirds
// of a depth image (uint16 millimetres, 0 = no reading), computed so that they fail safe:
//  - range gating: readings beyond max_range are free space; readings nearer than min_range are at min_range;
//  - a pixel with no reading counts as blocked at min_range, not as free (stereo depth has no reading exactly when
//    something is nearer than its minimum range);
//  - a zone's distance is the nearest distance that at least min_blob pixels share, so one noisy pixel does not stop
//    the robot while a 5 cm object at 30 cm (hundreds of pixels) does;
//  - a row band (roi_top..roi_bottom, fractions of the height) leaves out the floor;
//  - a reading older than max_age is unavailable.
// DepthFeed runs the synthetic depth scene (synthetic_scene.hpp) on its own thread, keeps the latest zones, and is
// the robot's sdk::ObstacleSource.
#pragma once

#include <rcand/sdk/interfaces/obstacle_source.hpp>
#include <rcand/sdk/stream.hpp>

#include <opencv2/core.hpp>

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "synthetic_scene.hpp"

namespace rcand::plugins::vision {

struct ZoneOptions {
  int min_range_mm = 200, max_range_mm = 4000;
  double min_blob_fraction = 0.001;  // of a zone's pixels (at least 9 pixels)
  double roi_top = 0.0, roi_bottom = 1.0;
};

struct Zones {
  bool available = false;
  double left_cm = 0, center_cm = 0, right_cm = 0, nearest_cm = 0;  // a free zone reads max_range
  std::int64_t timestamp_ms = 0;
  std::string reason;  // why unavailable
};

// The zones of one depth frame (CV_16UC1, millimetres).
Zones compute_zones(const cv::Mat& depth_mm, const ZoneOptions& options, std::int64_t timestamp_ms);

// A depth frame as a colour-mapped JPEG (near red, far blue, no reading black). Throws JpegError.
sdk::SharedBytes depth_jpeg(const cv::Mat& depth_mm, const ZoneOptions& options, int quality);

struct DepthSettings {
  bool enabled = false;
  int width = 640, height = 400;
  double fps = 15;
  ZoneOptions zones;
  std::chrono::milliseconds max_age{200};
};

class DepthFeed final : public sdk::ObstacleSource {
 public:
  explicit DepthFeed(DepthSettings settings);
  ~DepthFeed() override;
  DepthFeed(const DepthFeed&) = delete;
  DepthFeed& operator=(const DepthFeed&) = delete;

  void start();
  void stop() noexcept;
  // The latest zones, unavailable (reason "stale") when older than max_age. Any thread, never blocks beyond a copy.
  Zones zones() const;
  // sdk::ObstacleSource. Unavailable readings still carry the last frame's zones and timestamp_ms (0 before the
  // first frame), so a reader can say how stale the depth is.
  sdk::ObstacleReading obstacles() const noexcept override;
  // The latest depth frame (null before the first), for GET /api/depth/frame.
  std::shared_ptr<const cv::Mat> latest() const;
  const DepthSettings& settings() const noexcept { return settings_; }
  // Feeds one frame as the thread would (tests drive the scene themselves).
  void feed(const cv::Mat& depth_mm, std::int64_t timestamp_ms);
  // Renders the scene now and feeds it: what the thread does each period, and what a placement does at once.
  // Serialized, so a frame rendered before a placement is never fed after one that shows it. Any thread.
  void refresh();
  SyntheticScene& scene() noexcept { return scene_; }

 private:
  void run();

  const DepthSettings settings_;
  const std::chrono::steady_clock::time_point epoch_ = std::chrono::steady_clock::now();  // the scene's time 0
  SyntheticScene scene_;
  std::mutex refresh_mutex_;
  mutable std::mutex mutex_;
  std::condition_variable wake_;
  bool stopping_ = false;
  Zones zones_;
  std::chrono::steady_clock::time_point zones_at_{};
  std::shared_ptr<const cv::Mat> latest_;
  std::thread thread_;
};

}  // namespace rcand::plugins::vision
