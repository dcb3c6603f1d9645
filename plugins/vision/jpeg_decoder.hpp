// JPEG decoding with libjpeg-turbo's libjpeg API, beside the encoder (jpeg_encoder.hpp): snapshot cameras serve JPEG.
// One decoder keeps its decompressor from frame to frame; it is not thread-safe (one per thread). Every failure is a
// JpegError with libjpeg's own words; libjpeg never exits the process and never prints.
#pragma once

#include <opencv2/core.hpp>

#include <string_view>

#include "jpeg_encoder.hpp"

namespace rcand::plugins::vision {

class JpegDecoder {
 public:
  // Larger pictures are refused before any pixel memory is taken (a 20-byte header can claim 65535x65535).
  static constexpr long kMaxPixels = 7680L * 4320L;

  JpegDecoder();
  ~JpegDecoder();
  JpegDecoder(const JpegDecoder&) = delete;
  JpegDecoder& operator=(const JpegDecoder&) = delete;

  // The picture's size from its header alone (no pixel is decoded): what a pass-through checks. Throws JpegError when
  // `jpeg` is not a JPEG libjpeg can decode (not one, truncated header, unsupported colour space, too large).
  cv::Size size(std::string_view jpeg);
  // The whole picture as 8-bit BGR (grey pictures too). Throws JpegError.
  cv::Mat decode(std::string_view jpeg);

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace rcand::plugins::vision
