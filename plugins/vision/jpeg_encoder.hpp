// JPEG encoding with libjpeg-turbo's libjpeg API, directly: OpenCV's imgcodecs would do the same work but maps ~140
// libraries (GDAL, GDCM, TIFF, WebP...) into the robot for it (issue 32). One encoder keeps its compressor and its
// output buffer from frame to frame; it is not thread-safe (one per thread, or behind a lock).
#pragma once

#include <opencv2/core.hpp>

#include <memory>
#include <stdexcept>
#include <string_view>

namespace rcand::plugins::vision {

// Bad input (empty, not 8-bit BGR or grey) or a libjpeg failure, with libjpeg's own words.
class JpegError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class JpegEncoder {
 public:
  JpegEncoder();
  ~JpegEncoder();
  JpegEncoder(const JpegEncoder&) = delete;
  JpegEncoder& operator=(const JpegEncoder&) = delete;

  // `image`: 8-bit BGR (CV_8UC3) or grey (CV_8UC1), any stride; `quality` 1..100. The bytes stay valid until the next
  // call. Throws JpegError.
  std::string_view encode(const cv::Mat& image, int quality);

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace rcand::plugins::vision
