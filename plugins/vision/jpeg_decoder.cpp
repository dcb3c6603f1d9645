#include "jpeg_decoder.hpp"

#include <csetjmp>
#include <cstdio>  // jpeglib.h needs FILE and size_t declared first
#include <string>

#include <jpeglib.h>

#include "jpeg_errors.hpp"

namespace rcand::plugins::vision {

struct JpegDecoder::State {
  jpeg_decompress_struct cinfo{};
  JpegErrors errors{};

  // Only trivially destructible locals in these two: a libjpeg error longjmps back into their frame.
  bool read_header(std::string_view jpeg, int& width, int& height, int& components) {
    if (setjmp(errors.jump) != 0) {
      jpeg_abort_decompress(&cinfo);
      return false;
    }
    jpeg_mem_src(&cinfo, reinterpret_cast<const unsigned char*>(jpeg.data()), static_cast<unsigned long>(jpeg.size()));
    jpeg_read_header(&cinfo, TRUE);
    width = static_cast<int>(cinfo.image_width);
    height = static_cast<int>(cinfo.image_height);
    components = cinfo.num_components;
    return true;
  }
  // After read_header(): decodes into `out` (height x width, CV_8UC3).
  bool read_pixels(cv::Mat& out) {
    if (setjmp(errors.jump) != 0) {
      jpeg_abort_decompress(&cinfo);
      return false;
    }
    cinfo.out_color_space = JCS_EXT_BGR;
    jpeg_start_decompress(&cinfo);
    while (cinfo.output_scanline < cinfo.output_height) {
      JSAMPROW row = out.ptr<JSAMPLE>(static_cast<int>(cinfo.output_scanline));
      jpeg_read_scanlines(&cinfo, &row, 1);
    }
    jpeg_finish_decompress(&cinfo);
    return true;
  }
};

namespace {

[[noreturn]] void jpeg_decode_failed(const char* message) { throw JpegError(std::string("JPEG decoder: ") + message); }

}  // namespace

JpegDecoder::JpegDecoder() : state_(std::make_unique<State>()) {
  State& s = *state_;
  s.cinfo.err = s.errors.install();
  if (setjmp(s.errors.jump) != 0) jpeg_decode_failed(s.errors.message);
  jpeg_create_decompress(&s.cinfo);
}

JpegDecoder::~JpegDecoder() { jpeg_destroy_decompress(&state_->cinfo); }

cv::Size JpegDecoder::size(std::string_view jpeg) {
  State& s = *state_;
  if (jpeg.empty()) jpeg_decode_failed("the picture is empty");
  int width = 0, height = 0, components = 0;
  if (!s.read_header(jpeg, width, height, components)) jpeg_decode_failed(s.errors.message);
  jpeg_abort_decompress(&s.cinfo);  // ready for the next picture
  if (static_cast<long>(width) * height > kMaxPixels)
    jpeg_decode_failed(
        ("the picture is " + std::to_string(width) + "x" + std::to_string(height) + ", larger than 7680x4320").c_str());
  if (components != 1 && components != 3)
    jpeg_decode_failed(("the picture has " + std::to_string(components) + " colour components (CMYK?), not 1 or 3").c_str());
  return {width, height};
}

cv::Mat JpegDecoder::decode(std::string_view jpeg) {
  const cv::Size picture = size(jpeg);  // checks it, before the pixel memory is taken
  State& s = *state_;
  cv::Mat out(picture, CV_8UC3);
  int width = 0, height = 0, components = 0;
  if (!s.read_header(jpeg, width, height, components) || !s.read_pixels(out)) jpeg_decode_failed(s.errors.message);
  return out;
}

}  // namespace rcand::plugins::vision
