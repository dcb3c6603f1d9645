// Camera sources behind one interface: a synthetic test pattern, a video file played in a loop, a V4L2 device, a
// network URL (HTTP MJPEG or RTSP through OpenCV's FFmpeg backend) and an HTTP snapshot URL polled at the camera's fps. Only the
// capture thread calls them: open() and read() may block (a URL for its open/read timeouts, a device for a frame), so no request
// thread ever does. The synthetic source is here, the snapshot source in snapshot_source.cpp; the file, device and URL sources
// are in the video backend module (video_backend.hpp).
#pragma once

#include <opencv2/core.hpp>

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>

namespace rcand::plugins::vision {

// A named fault: what is wrong, in words an operator can act on ("camera device /dev/video3 does not exist").
class SourceError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

enum class SourceKind { Synthetic, File, V4l2, Url, Snapshot };

struct SourceSettings {
  SourceKind kind = SourceKind::Synthetic;
  std::string location;  // file path, /dev/videoN, or URL; empty for the synthetic source
  int width = 640, height = 480;
  bool size_given = false;  // the camera block set the size; else a snapshot camera's own size is kept
  double fps = 30.0;        // a file: 0 plays it at its own rate
  std::string fourcc;       // V4L2 pixel format asked for ("MJPG", "YUYV"); empty: the driver's default
  std::chrono::milliseconds open_timeout{3000}, read_timeout{3000};  // URL (FFmpeg backend) and snapshot sources
  std::size_t snapshot_max_bytes = 8u << 20;                         // a snapshot camera's largest answer
};

// One frame as a source delivers it: decoded pixels, or the camera's own JPEG passed through to viewers as it is
// (`image` empty, `jpeg` and `size` set) when the camera already serves JPEG of the size asked for - no decode and
// no encode (what ustreamer does with a camera's MJPEG).
struct CameraFrame {
  cv::Mat image;
  std::shared_ptr<const std::string> jpeg;
  cv::Size size;
};

std::string_view kind_name(SourceKind kind) noexcept;

class FrameSource {
 public:
  virtual ~FrameSource() = default;
  // Opens the device, file or URL; throws SourceError naming the fault.
  virtual void open() = 0;
  // The next frame (BGR, 8 bits). false: the source is lost (unplugged, stream ended, read timed out); throws
  // SourceError when the reason is known (the file disappeared).
  virtual bool read(cv::Mat& frame) = 0;
  // The next frame, as read() or as the camera's own JPEG (CameraFrame). This default decodes: read().
  virtual bool read_frame(CameraFrame& frame) {
    frame.jpeg.reset();
    if (!read(frame.image)) return false;
    frame.size = frame.image.size();
    return true;
  }
  // true: read() returns at once and the capture thread paces it at fps (synthetic, file); false: read() waits for
  // the device's next frame.
  virtual bool paced() const noexcept = 0;
  // Frames per second: the pace of a paced source; what the device reports otherwise (0: unknown). After open().
  virtual double fps() const noexcept = 0;
  // true: a frame nobody asked for costs work and nothing else (synthetic): the capture thread skips it.
  virtual bool skip_when_unwatched() const noexcept { return false; }
  // "synthetic 640x480", "file /srv/demo.avi", "v4l2 /dev/video0", "url rtsp://cam/...", "snapshot http://cam/..."
  // (no credentials).
  virtual std::string describe() const = 0;
};

// A file, device or URL source loads the video backend module first: throws SourceError if it is missing.
std::unique_ptr<FrameSource> make_source(const SourceSettings& settings);
// An HTTP snapshot camera (snapshot_source.cpp); throws SourceError for a URL it cannot poll.
std::unique_ptr<FrameSource> make_snapshot_source(const SourceSettings& settings);

// The synthetic source's picture for frame `number` at wall time `wall_ms`: colour bars, a box moving across them,
// the frame counter and the time.
void draw_test_pattern(cv::Mat& frame, std::uint64_t number, std::int64_t wall_ms);
// What viewers see while the camera is down: "NO SIGNAL", why, and the time (so a frozen picture is told apart).
cv::Mat no_signal_frame(int width, int height, const std::string& reason, std::int64_t wall_ms);

// A URL with any user:password@ removed, for logs and status.
std::string redact_url(const std::string& url);

}  // namespace rcand::plugins::vision
