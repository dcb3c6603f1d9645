// The real camera sources - a video file played in a loop, a V4L2 device, a network URL - on OpenCV's videoio: the
// video backend module (rcand_vision_videoio.so), which the vision plugin loads only when the camera block names one
// of them (video_backend.hpp). videoio brings FFmpeg and GStreamer: ~220 libraries and ~0.5 s to map them, which a
// robot on the synthetic camera never pays (issue 32).
#include <opencv2/videoio.hpp>

#include <sys/stat.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <new>
#include <vector>

#include "camera_source.hpp"
#include "video_backend.hpp"

namespace rcand::plugins::vision {
namespace {

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
}  // namespace rcand::plugins::vision

// The module's one entry (video_backend.hpp): nullptr when out of memory, or for a kind it has no source for.
extern "C" __attribute__((visibility("default"))) rcand::plugins::vision::FrameSource* RCAND_VISION_VIDEOIO_ENTRY(
    const rcand::plugins::vision::SourceSettings& settings) noexcept {
  using namespace rcand::plugins::vision;
  try {
    switch (settings.kind) {
      case SourceKind::File: return new FileSource(settings);
      case SourceKind::V4l2: return new V4l2Source(settings);
      case SourceKind::Url: return new UrlSource(settings);
      case SourceKind::Synthetic:
      case SourceKind::Snapshot: break;
    }
  } catch (const std::bad_alloc&) {
  }
  return nullptr;
}
