#include "depth.hpp"

#include "jpeg_encoder.hpp"

#include <opencv2/imgproc.hpp>

#include <pthread.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

namespace rcand::plugins::vision {
namespace {

std::int64_t depth_wall_ms() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::system_clock::now().time_since_epoch()).count();
}

// The nearest distance (cm) that at least `need` pixels of the zone share, or max_cm when the zone is free.
double zone_distance(const cv::Mat& depth, int top, int bottom, int x0, int x1, const ZoneOptions& o) {
  const int min_cm = o.min_range_mm / 10, max_cm = o.max_range_mm / 10;
  std::vector<std::uint32_t> histogram(static_cast<std::size_t>(max_cm) + 1, 0);
  for (int y = top; y < bottom; ++y) {
    const auto* row = depth.ptr<std::uint16_t>(y);
    for (int x = x0; x < x1; ++x) {
      const int mm = row[x];
      if (mm > o.max_range_mm) continue;  // beyond the range: free
      // No reading (0) or nearer than the sensor's minimum: blocked at the minimum, never free.
      ++histogram[static_cast<std::size_t>(mm < o.min_range_mm ? min_cm : mm / 10)];
    }
  }
  const double pixels = static_cast<double>(bottom - top) * (x1 - x0);
  const auto need = std::max<std::uint64_t>(9, static_cast<std::uint64_t>(std::ceil(pixels * o.min_blob_fraction)));
  std::uint64_t seen = 0;
  for (int cm = min_cm; cm <= max_cm; ++cm) {
    seen += histogram[static_cast<std::size_t>(cm)];
    if (seen >= need) return cm;
  }
  return max_cm;
}

}  // namespace

Zones compute_zones(const cv::Mat& depth, const ZoneOptions& o, std::int64_t timestamp_ms) {
  Zones z;
  z.timestamp_ms = timestamp_ms;
  if (depth.empty() || depth.type() != CV_16UC1) {
    z.reason = "no depth frame";
    return z;
  }
  const int top = std::clamp(static_cast<int>(o.roi_top * depth.rows), 0, depth.rows);
  const int bottom = std::clamp(static_cast<int>(o.roi_bottom * depth.rows), top, depth.rows);
  if (bottom == top || depth.cols < 3) {
    z.reason = "the depth region of interest is empty";
    return z;
  }
  std::array<double, 3> zone{};
  for (int i = 0; i < 3; ++i) zone[i] = zone_distance(depth, top, bottom, i * depth.cols / 3, (i + 1) * depth.cols / 3, o);
  z.available = true;
  z.left_cm = zone[0];
  z.center_cm = zone[1];
  z.right_cm = zone[2];
  z.nearest_cm = std::min({zone[0], zone[1], zone[2]});
  return z;
}

sdk::SharedBytes depth_jpeg(const cv::Mat& depth, const ZoneOptions& o, int quality) {
  const double span = std::max(1, o.max_range_mm - o.min_range_mm);
  cv::Mat scaled, colour;
  depth.convertTo(scaled, CV_8U, -255.0 / span, 255.0 * o.max_range_mm / span);  // near 255, far 0 (saturated)
  cv::applyColorMap(scaled, colour, cv::COLORMAP_JET);
  colour.setTo(cv::Scalar(0, 0, 0), depth == 0);
  JpegEncoder jpeg;  // a depth snapshot is rare: no encoder kept between them
  return std::make_shared<const std::string>(jpeg.encode(colour, quality));
}

DepthFeed::DepthFeed(DepthSettings settings) : settings_(settings) { zones_.reason = "no depth frame yet"; }

DepthFeed::~DepthFeed() { stop(); }

void DepthFeed::start() {
  if (thread_.joinable()) return;
  thread_ = std::thread([this] {
    ::pthread_setname_np(::pthread_self(), "vision.depth");
    run();
  });
}

void DepthFeed::stop() noexcept {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void DepthFeed::run() {
  using Clock = std::chrono::steady_clock;
  const auto period = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / settings_.fps));
  auto due = Clock::now();
  std::unique_lock lock(mutex_);
  while (!stopping_) {
    lock.unlock();
    refresh();
    lock.lock();
    due += period;
    wake_.wait_until(lock, due, [&] { return stopping_; });
  }
}

void DepthFeed::refresh() {
  std::lock_guard order(refresh_mutex_);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - epoch_).count();
  feed(scene_.render(settings_.width, settings_.height, seconds), depth_wall_ms());
}

void DepthFeed::feed(const cv::Mat& depth, std::int64_t timestamp_ms) {
  Zones zones = compute_zones(depth, settings_.zones, timestamp_ms);
  auto frame = std::make_shared<const cv::Mat>(depth);
  std::lock_guard lock(mutex_);
  zones_ = std::move(zones);
  zones_at_ = std::chrono::steady_clock::now();
  latest_ = std::move(frame);
}

Zones DepthFeed::zones() const {
  std::lock_guard lock(mutex_);
  Zones zones = zones_;
  const auto age = std::chrono::steady_clock::now() - zones_at_;
  if (zones.available && age > settings_.max_age) {
    zones.available = false;
    zones.reason = "stale: the last depth frame is " +
                   std::to_string(std::chrono::duration_cast<std::chrono::milliseconds>(age).count()) + " ms old";
  }
  return zones;
}

sdk::ObstacleReading DepthFeed::obstacles() const noexcept {
  try {
    const Zones z = zones();
    // Dated only while it is a real reading or a stale one: a frame that gave no zones has no reading to date.
    const bool dated = z.available || z.reason.rfind("stale", 0) == 0;
    return {z.available, z.left_cm, z.center_cm, z.right_cm, z.nearest_cm, dated ? z.timestamp_ms : 0};
  } catch (...) {  // out of memory copying the reason: report no reading, which is not "clear"
    return {};
  }
}

std::shared_ptr<const cv::Mat> DepthFeed::latest() const {
  std::lock_guard lock(mutex_);
  return latest_;
}

}  // namespace rcand::plugins::vision
