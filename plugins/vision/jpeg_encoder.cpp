#include "jpeg_encoder.hpp"

#include <algorithm>
#include <csetjmp>
#include <cstdio>  // jpeglib.h needs FILE and size_t declared first
#include <string>
#include <vector>

#include <jpeglib.h>
// after jpeglib.h, which it needs
#include <jerror.h>

#include "jpeg_errors.hpp"

namespace rcand::plugins::vision {

// The output goes into `out`, grown by doubling and kept for the next frame: no allocation per frame once it has
// seen the largest one.
struct JpegEncoder::State {
  jpeg_compress_struct cinfo{};
  JpegErrors errors{};
  jpeg_destination_mgr destination{};
  std::vector<JOCTET> out;
  std::size_t used = 0;
  bool out_of_memory = false;
  std::vector<JSAMPROW> rows;

  static State& of(j_compress_ptr cinfo) { return *static_cast<State*>(cinfo->client_data); }

  static void start(j_compress_ptr cinfo) {
    State& s = of(cinfo);
    s.destination.next_output_byte = s.out.data();
    s.destination.free_in_buffer = s.out.size();
  }
  static boolean grow(j_compress_ptr cinfo) {  // called when the buffer is full: all of it is written
    State& s = of(cinfo);
    const std::size_t written = s.out.size();
    try {
      s.out.resize(written * 2);
    } catch (...) {
      s.out_of_memory = true;
    }
    if (s.out_of_memory) ERREXIT(cinfo, JERR_OUT_OF_MEMORY);  // outside the catch: longjmp leaves no live exception
    s.destination.next_output_byte = s.out.data() + written;
    s.destination.free_in_buffer = s.out.size() - written;
    return TRUE;
  }
  static void finish(j_compress_ptr cinfo) {
    State& s = of(cinfo);
    s.used = s.out.size() - s.destination.free_in_buffer;
  }

  // Only trivially destructible locals here: a libjpeg error longjmps back into this frame.
  bool compress(int width, int height, int channels, int quality) {
    if (setjmp(errors.jump) != 0) {
      jpeg_abort_compress(&cinfo);  // ready for the next frame
      return false;
    }
    cinfo.image_width = static_cast<JDIMENSION>(width);
    cinfo.image_height = static_cast<JDIMENSION>(height);
    cinfo.input_components = channels;
    cinfo.in_color_space = channels == 3 ? JCS_EXT_BGR : JCS_GRAYSCALE;
    jpeg_set_defaults(&cinfo);
    jpeg_set_quality(&cinfo, quality, TRUE);
    jpeg_start_compress(&cinfo, TRUE);
    while (cinfo.next_scanline < cinfo.image_height)
      jpeg_write_scanlines(&cinfo, rows.data() + cinfo.next_scanline, cinfo.image_height - cinfo.next_scanline);
    jpeg_finish_compress(&cinfo);
    return true;
  }
};

JpegEncoder::JpegEncoder() : state_(std::make_unique<State>()) {
  State& s = *state_;
  s.cinfo.err = s.errors.install();
  if (setjmp(s.errors.jump) != 0) throw JpegError(std::string("JPEG encoder: ") + s.errors.message);
  jpeg_create_compress(&s.cinfo);
  s.cinfo.client_data = &s;
  s.destination.init_destination = State::start;
  s.destination.empty_output_buffer = State::grow;
  s.destination.term_destination = State::finish;
  s.cinfo.dest = &s.destination;
}

JpegEncoder::~JpegEncoder() { jpeg_destroy_compress(&state_->cinfo); }

std::string_view JpegEncoder::encode(const cv::Mat& image, int quality) {
  if (image.empty()) throw JpegError("JPEG encoder: the image is empty");
  if (image.type() != CV_8UC3 && image.type() != CV_8UC1)
    throw JpegError("JPEG encoder: the image must be 8-bit BGR or grey, not OpenCV type " + cv::typeToString(image.type()));
  if (image.dims != 2) throw JpegError("JPEG encoder: the image must be 2-dimensional");
  State& s = *state_;
  s.rows.resize(static_cast<std::size_t>(image.rows));
  for (int r = 0; r < image.rows; ++r) s.rows[static_cast<std::size_t>(r)] = const_cast<JSAMPROW>(image.ptr<JSAMPLE>(r));
  // A first guess big enough for most frames: a quarter of the raw size, at least 16 KiB.
  const std::size_t guess = std::max<std::size_t>(16 * 1024, image.total() * image.elemSize() / 4);
  if (s.out.size() < guess) s.out.resize(guess);
  s.out_of_memory = false;
  if (!s.compress(image.cols, image.rows, image.channels(), std::clamp(quality, 1, 100)))
    throw JpegError(std::string("JPEG encoder: ") + s.errors.message);
  return {reinterpret_cast<const char*>(s.out.data()), s.used};
}

}  // namespace rcand::plugins::vision
