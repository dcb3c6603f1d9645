#include "camera_source.hpp"

#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include <sys/stat.h>

#include <array>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>

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

class FileSource final : public FrameSource {
 public:
  explicit FileSource(const SourceSettings& s) : path_(s.location), fps_(s.fps) {}
  void open() override {
    require_file();
    if (!reopen() || !capture_.read(first_) || first_.empty())
      throw SourceError("video file " + path_ + " is not a video OpenCV can read");
    if (fps_ <= 0) {
      const double own = capture_.get(cv::CAP_PROP_FPS);
      fps_ = std::isfinite(own) && own > 0 && own <= 240 ? own : 30.0;
    }
    // Checked about once a second: an unlinked file stays readable through its open descriptor.
    check_every_ = std::max(1, static_cast<int>(std::lround(fps_)));
  }
  bool read(cv::Mat& frame) override {
    if (!first_.empty()) {
      frame = std::move(first_);
      first_ = cv::Mat();
      return true;
    }
    if (++since_check_ >= check_every_) {
      since_check_ = 0;
      require_file();
    }
    if (capture_.read(frame) && !frame.empty()) return true;
    // The end: play it again from the start, reopened so that a replaced or removed file is noticed.
    require_file();
    if (!reopen() || !capture_.read(frame) || frame.empty()) throw SourceError("video file " + path_ + " can no longer be read");
    return true;
  }
  bool paced() const noexcept override { return true; }
  double fps() const noexcept override { return fps_; }
  std::string describe() const override { return "file " + path_; }

 private:
  // FFmpeg reads every container; OpenCV's own MJPEG reader is the fallback where it is missing. Named backends
  // only: CAP_ANY would also try GStreamer and image sequences, each logging its own failure.
  bool reopen() {
    capture_.release();
    return capture_.open(path_, cv::CAP_FFMPEG) || capture_.open(path_, cv::CAP_OPENCV_MJPEG);
  }
  void require_file() const {
    std::error_code ec;
    if (!std::filesystem::exists(path_, ec)) throw SourceError("video file " + path_ + " does not exist");
    if (!std::filesystem::is_regular_file(path_, ec)) throw SourceError("video file " + path_ + " is not a regular file");
  }

  std::string path_;
  double fps_;
  cv::VideoCapture capture_;
  cv::Mat first_;
  int check_every_ = 30, since_check_ = 0;
};

class V4l2Source final : public FrameSource {
 public:
  explicit V4l2Source(const SourceSettings& s) : settings_(s) {}
  void open() override {
    const std::string& device = settings_.location;
    struct stat info {};
    if (::stat(device.c_str(), &info) != 0) throw SourceError("camera device " + device + " does not exist");
    if (!S_ISCHR(info.st_mode)) throw SourceError("camera device " + device + " is not a character device");
    if (!capture_.open(device, cv::CAP_V4L2))
      throw SourceError("camera device " + device +
                        " could not be opened (in use, not a capture device, or no "
                        "permission: is rcand in the video group?)");
    if (settings_.fourcc.size() == 4) {
      const auto& f = settings_.fourcc;
      capture_.set(cv::CAP_PROP_FOURCC, cv::VideoWriter::fourcc(f[0], f[1], f[2], f[3]));
    }
    capture_.set(cv::CAP_PROP_FRAME_WIDTH, settings_.width);
    capture_.set(cv::CAP_PROP_FRAME_HEIGHT, settings_.height);
    capture_.set(cv::CAP_PROP_FPS, settings_.fps);
    capture_.set(cv::CAP_PROP_BUFFERSIZE, 1);  // the newest frame, not a queue of old ones
  }
  bool read(cv::Mat& frame) override { return capture_.read(frame) && !frame.empty(); }
  bool paced() const noexcept override { return false; }
  double fps() const noexcept override { return capture_.get(cv::CAP_PROP_FPS); }
  std::string describe() const override { return "v4l2 " + settings_.location; }

 private:
  SourceSettings settings_;
  cv::VideoCapture capture_;
};

class UrlSource final : public FrameSource {
 public:
  explicit UrlSource(const SourceSettings& s) : settings_(s) {}
  void open() override {
    // The timeouts apply only when the FFmpeg backend is named (OpenCV 4.5.4+); without them a dead host holds
    // open() and read() for 30 s.
    const std::vector<int> params{cv::CAP_PROP_OPEN_TIMEOUT_MSEC, static_cast<int>(settings_.open_timeout.count()),
                                  cv::CAP_PROP_READ_TIMEOUT_MSEC, static_cast<int>(settings_.read_timeout.count())};
    if (!capture_.open(settings_.location, cv::CAP_FFMPEG, params))
      throw SourceError("camera URL " + redact_url(settings_.location) + " did not open within " +
                        std::to_string(settings_.open_timeout.count()) + " ms, or is not a video stream");
  }
  bool read(cv::Mat& frame) override { return capture_.read(frame) && !frame.empty(); }
  bool paced() const noexcept override { return false; }
  double fps() const noexcept override { return capture_.get(cv::CAP_PROP_FPS); }
  std::string describe() const override { return "url " + redact_url(settings_.location); }

 private:
  SourceSettings settings_;
  cv::VideoCapture capture_;
};

}  // namespace

std::string_view kind_name(SourceKind kind) noexcept {
  switch (kind) {
    case SourceKind::Synthetic: return "synthetic";
    case SourceKind::File: return "file";
    case SourceKind::V4l2: return "v4l2";
    case SourceKind::Url: return "url";
  }
  return "unknown";
}

std::unique_ptr<FrameSource> make_source(const SourceSettings& settings) {
  switch (settings.kind) {
    case SourceKind::Synthetic: return std::make_unique<SyntheticSource>(settings);
    case SourceKind::File: return std::make_unique<FileSource>(settings);
    case SourceKind::V4l2: return std::make_unique<V4l2Source>(settings);
    case SourceKind::Url: return std::make_unique<UrlSource>(settings);
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

std::string redact_url(const std::string& url) {
  const auto scheme = url.find("://");
  if (scheme == std::string::npos) return url;
  const auto host_start = scheme + 3;
  const auto path = url.find('/', host_start);
  const auto at = url.rfind('@', path == std::string::npos ? std::string::npos : path);
  if (at == std::string::npos || at < host_start) return url;
  return url.substr(0, host_start) + "***@" + url.substr(at + 1);
}

}  // namespace rcand::plugins::vision
