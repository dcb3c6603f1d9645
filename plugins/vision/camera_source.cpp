#include "camera_source.hpp"

#include "video_backend.hpp"

#include <opencv2/imgproc.hpp>

#include <array>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <ctime>

namespace rcand::plugins::vision {
namespace {

std::string clock_text(std::int64_t wall_ms) {
  const std::time_t seconds = static_cast<std::time_t>(wall_ms / 1000);
  std::tm tm{};
  gmtime_r(&seconds, &tm);
  std::array<char, 48> text{};
  std::snprintf(text.data(), text.size(), "%04d-%02d-%02d %02d:%02d:%02d.%03d UTC", tm.tm_year + 1900, tm.tm_mon + 1, tm.tm_mday,
                tm.tm_hour, tm.tm_min, tm.tm_sec, static_cast<int>(wall_ms % 1000));
  return text.data();
}

std::int64_t wall_now_ms() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::system_clock::now().time_since_epoch()).count();
}

// Text with a dark outline, readable on any background. Not anti-aliased: that costs 4x as much per frame.
void label(cv::Mat& frame, const std::string& text, cv::Point at, double scale) {
  const int thick = std::max(1, static_cast<int>(std::lround(scale * 2)));
  cv::putText(frame, text, at, cv::FONT_HERSHEY_SIMPLEX, scale, cv::Scalar(0, 0, 0), thick + 2, cv::LINE_8);
  cv::putText(frame, text, at, cv::FONT_HERSHEY_SIMPLEX, scale, cv::Scalar(255, 255, 255), thick, cv::LINE_8);
}

void draw_bars(cv::Mat& frame) {
  static const std::array<cv::Scalar, 8> kBars{
      {{192, 192, 192}, {0, 192, 192}, {192, 192, 0}, {0, 192, 0}, {192, 0, 192}, {0, 0, 192}, {192, 0, 0}, {16, 16, 16}}};
  const int w = frame.cols, h = frame.rows;
  for (int i = 0; i < 8; ++i) cv::rectangle(frame, cv::Rect(i * w / 8, 0, (i + 1) * w / 8 - i * w / 8, h), kBars[i], cv::FILLED);
}

// What moves: a box crossing the picture (once every 4 seconds at 30 fps), the frame counter and the time.
void draw_moving(cv::Mat& frame, std::uint64_t number, std::int64_t wall_ms) {
  const int w = frame.cols, h = frame.rows;
  const int box = std::max(8, h / 6);
  const int travel = std::max(1, w - box);
  const int x = static_cast<int>(number * 4 % static_cast<std::uint64_t>(2 * travel));
  const cv::Rect where(x < travel ? x : 2 * travel - x, h / 2 - box / 2, box, box);
  cv::rectangle(frame, where, cv::Scalar(255, 255, 255), cv::FILLED);
  cv::rectangle(frame, where, cv::Scalar(0, 0, 0), 2);
  const double scale = std::max(0.4, h / 600.0);
  label(frame, "rcand synthetic  frame " + std::to_string(number), cv::Point(w / 40, h / 8), scale);
  label(frame, clock_text(wall_ms), cv::Point(w / 40, h - h / 12), scale);
}

class SyntheticSource final : public FrameSource {
 public:
  explicit SyntheticSource(const SourceSettings& s) : width_(s.width), height_(s.height), fps_(s.fps) {}
  void open() override {}
  bool read(cv::Mat& frame) override {
    if (background_.empty()) {  // the bars never change: drawn once, copied per frame
      background_.create(height_, width_, CV_8UC3);
      draw_bars(background_);
    }
    background_.copyTo(frame);  // a fresh Mat each time: the previous frame may still be in the hub
    draw_moving(frame, number_++, wall_now_ms());
    return true;
  }
  bool paced() const noexcept override { return true; }
  double fps() const noexcept override { return fps_; }
  bool skip_when_unwatched() const noexcept override { return true; }
  std::string describe() const override { return "synthetic " + std::to_string(width_) + "x" + std::to_string(height_); }

 private:
  int width_, height_;
  double fps_;
  std::uint64_t number_ = 0;
  cv::Mat background_;
};

}  // namespace

std::string_view kind_name(SourceKind kind) noexcept {
  switch (kind) {
    case SourceKind::Synthetic: return "synthetic";
    case SourceKind::File: return "file";
    case SourceKind::V4l2: return "v4l2";
    case SourceKind::Url: return "url";
    case SourceKind::Snapshot: return "snapshot";
  }
  return "unknown";
}

std::unique_ptr<FrameSource> make_source(const SourceSettings& settings) {
  switch (settings.kind) {
    case SourceKind::Synthetic: return std::make_unique<SyntheticSource>(settings);
    case SourceKind::File:
    case SourceKind::V4l2:
    case SourceKind::Url: return make_video_source(settings);
    case SourceKind::Snapshot: return make_snapshot_source(settings);
  }
  throw SourceError("unknown camera source");
}

void draw_test_pattern(cv::Mat& frame, std::uint64_t number, std::int64_t wall_ms) {
  draw_bars(frame);
  draw_moving(frame, number, wall_ms);
}

cv::Mat no_signal_frame(int width, int height, const std::string& reason, std::int64_t wall_ms) {
  cv::Mat frame(height, width, CV_8UC3, cv::Scalar(40, 40, 40));
  const double scale = std::max(0.4, height / 480.0);
  label(frame, "NO SIGNAL", cv::Point(width / 2 - static_cast<int>(150 * scale), height / 2), 1.6 * scale);
  label(frame, reason.size() > 60 ? reason.substr(0, 57) + "..." : reason, cv::Point(width / 40, height / 2 + height / 8),
        0.5 * scale);
  label(frame, clock_text(wall_ms), cv::Point(width / 40, height - height / 12), 0.6 * scale);
  return frame;
}

}  // namespace rcand::plugins::vision
