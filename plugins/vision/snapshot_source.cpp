// An HTTP snapshot camera: a URL that answers one JPEG per GET (IP cameras, ESP32-CAM's /capture, the reference
// runtime's `http` camera), polled at the camera's fps on one kept-alive connection (snapshot_client.hpp). OpenCV's
// videoio cannot poll a snapshot (it opens a stream), so this source is in the plugin itself and never loads the
// video backend module. When the picture is already of the size asked for (or no size was asked for), the camera's
// own JPEG goes to viewers as it is: its header is read and checked, no pixel is decoded and none re-encoded. Else it
// is decoded with libjpeg-turbo and scaled to the size asked for, and the hub encodes it as any frame.
#include <opencv2/imgproc.hpp>

#include "camera_source.hpp"
#include "jpeg_decoder.hpp"
#include "snapshot_client.hpp"

namespace rcand::plugins::vision {
namespace {

class SnapshotSource final : public FrameSource {
 public:
  explicit SnapshotSource(const SourceSettings& s)
      : settings_(s), client_(s.location, SnapshotLimits{s.open_timeout, s.read_timeout, s.snapshot_max_bytes}) {}

  // The first picture is fetched here: a camera that does not answer is a fault of open(), not a source that opens
  // and fails at once (which would report "camera back" between faults).
  void open() override { fetch(first_); }
  bool read_frame(CameraFrame& frame) override {
    if (first_.jpeg || !first_.image.empty()) {
      frame = std::move(first_);
      first_ = CameraFrame{};
      return true;
    }
    fetch(frame);
    return true;
  }
  bool read(cv::Mat& image) override {
    CameraFrame frame;
    if (!read_frame(frame)) return false;
    image = frame.image.empty() ? decoder_.decode(*frame.jpeg) : std::move(frame.image);
    return true;
  }
  bool paced() const noexcept override { return true; }
  double fps() const noexcept override { return settings_.fps; }
  std::string describe() const override { return "snapshot " + redact_url(settings_.location); }

 private:
  // The next picture into `frame`; throws SourceError naming the fault.
  void fetch(CameraFrame& frame) {
    auto jpeg = client_.fetch();
    try {
      const cv::Size size = decoder_.size(*jpeg);
      const cv::Size wanted(settings_.width, settings_.height);
      if (!settings_.size_given || size == wanted) {
        frame.jpeg = std::move(jpeg);
        frame.size = size;
        return;
      }
      frame.jpeg.reset();
      cv::resize(decoder_.decode(*jpeg), frame.image, wanted, 0, 0, cv::INTER_AREA);
      frame.size = wanted;
    } catch (const JpegError& e) {
      throw SourceError("snapshot " + redact_url(settings_.location) + ": the answer is not a picture rcand can use (" +
                        e.what() + ")");
    }
  }

  SourceSettings settings_;
  SnapshotClient client_;
  JpegDecoder decoder_;
  CameraFrame first_;
};

}  // namespace

std::unique_ptr<FrameSource> make_snapshot_source(const SourceSettings& settings) {
  return std::make_unique<SnapshotSource>(settings);
}

}  // namespace rcand::plugins::vision
