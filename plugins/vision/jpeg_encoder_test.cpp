// The vision plugin's own JPEG encoder (libjpeg-turbo, issue 32): what it writes decodes (with OpenCV's imgcodecs, an
// independent decoder) to the input within JPEG's loss, at odd and large sizes and several qualities, in BGR and grey,
// from a strided view; its buffers carry nothing from one frame to the next; bad input and libjpeg's own errors are
// a clear JpegError, after which the encoder still works.
#include <doctest/doctest.h>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <cmath>
#include <string>
#include <vector>

#include "jpeg_encoder.hpp"

using rcand::plugins::vision::JpegEncoder;
using rcand::plugins::vision::JpegError;

namespace {

// Smooth colour waves plus the hard edges of 32-pixel blocks: what a camera sees, and what JPEG can keep.
cv::Mat jpeg_test_picture(int width, int height) {
  cv::Mat image(height, width, CV_8UC3);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x)
      image.at<cv::Vec3b>(y, x) = cv::Vec3b(cv::saturate_cast<uchar>(128 + 90 * std::sin(x / 40.0)),
                                            cv::saturate_cast<uchar>(128 + 90 * std::cos(y / 30.0)),
                                            static_cast<uchar>((x / 32 + y / 32) % 2 ? 200 : 60));
  return image;
}

cv::Mat jpeg_decode(std::string_view bytes, int flags) {
  return cv::imdecode(std::vector<uchar>(bytes.begin(), bytes.end()), flags);
}

// Peak signal to noise ratio in dB (infinite for identical images).
double jpeg_psnr(const cv::Mat& a, const cv::Mat& b) { return cv::PSNR(a, b); }

}  // namespace

TEST_CASE("jpeg encoder: BGR frames decode to the input within JPEG's loss, at several sizes and qualities") {
  JpegEncoder encoder;
  const std::vector<cv::Size> sizes{{1, 1}, {7, 5}, {16, 16}, {161, 119}, {640, 480}, {1283, 721}};
  for (const auto& size : sizes)
    for (const int quality : {30, 80, 95}) {
      const cv::Mat input = jpeg_test_picture(size.width, size.height);
      const std::string bytes(encoder.encode(input, quality));
      const cv::Mat output = jpeg_decode(bytes, cv::IMREAD_COLOR);
      const std::string where = std::to_string(size.width) + "x" + std::to_string(size.height) + " q" + std::to_string(quality);
      INFO(where);
      REQUIRE_FALSE(output.empty());
      CHECK(output.size() == input.size());
      CHECK(output.type() == CV_8UC3);
      CHECK(bytes.substr(0, 2) == "\xFF\xD8");  // SOI
      CHECK(jpeg_psnr(input, output) > (quality >= 80 ? 30.0 : 25.0));
    }
}

TEST_CASE("jpeg encoder: a higher quality is larger and closer to the input") {
  JpegEncoder encoder;
  const cv::Mat input = jpeg_test_picture(320, 240);
  const std::string low(encoder.encode(input, 20)), high(encoder.encode(input, 95));
  CHECK(low.size() < high.size());
  CHECK(jpeg_psnr(input, jpeg_decode(low, cv::IMREAD_COLOR)) < jpeg_psnr(input, jpeg_decode(high, cv::IMREAD_COLOR)));
}

TEST_CASE("jpeg encoder: grey frames stay grey; a strided view encodes as its copy does") {
  JpegEncoder encoder;
  cv::Mat grey(90, 130, CV_8UC1);
  for (int y = 0; y < grey.rows; ++y)
    for (int x = 0; x < grey.cols; ++x) grey.at<uchar>(y, x) = static_cast<uchar>((x * 2 + y) % 256);
  const cv::Mat decoded = jpeg_decode(encoder.encode(grey, 90), cv::IMREAD_UNCHANGED);
  REQUIRE_FALSE(decoded.empty());
  CHECK(decoded.type() == CV_8UC1);
  CHECK(jpeg_psnr(grey, decoded) > 30.0);

  const cv::Mat big = jpeg_test_picture(400, 300);
  const cv::Mat view = big(cv::Rect(13, 7, 201, 150));  // rows 400 pixels apart: not continuous
  REQUIRE_FALSE(view.isContinuous());
  CHECK(std::string(encoder.encode(view, 80)) == std::string(encoder.encode(view.clone(), 80)));
}

TEST_CASE("jpeg encoder: a reused encoder writes what a fresh one writes, after a larger and a smaller frame") {
  JpegEncoder reused;
  const cv::Mat small = jpeg_test_picture(64, 48), large = jpeg_test_picture(1600, 1200);
  const std::string first(reused.encode(small, 80));
  const std::string big(reused.encode(large, 95));  // grows the buffer past its first guess
  const std::string again(reused.encode(small, 80));
  CHECK(first == again);
  JpegEncoder fresh;
  CHECK(std::string(fresh.encode(large, 95)) == big);
}

TEST_CASE("jpeg encoder: bad input is a clear error, and the encoder still works after it") {
  JpegEncoder encoder;
  CHECK_THROWS_WITH_AS(encoder.encode(cv::Mat(), 80), "JPEG encoder: the image is empty", JpegError);
  CHECK_THROWS_WITH_AS(encoder.encode(cv::Mat(4, 4, CV_16UC1, cv::Scalar(0)), 80),
                       "JPEG encoder: the image must be 8-bit BGR or grey, not OpenCV type CV_16UC1", JpegError);
  CHECK_THROWS_WITH_AS(encoder.encode(cv::Mat(4, 4, CV_8UC4, cv::Scalar(0)), 80),
                       "JPEG encoder: the image must be 8-bit BGR or grey, not OpenCV type CV_8UC4", JpegError);
  CHECK_THROWS_WITH_AS(encoder.encode(cv::Mat(4, 4, CV_32FC3, cv::Scalar(0)), 80),
                       "JPEG encoder: the image must be 8-bit BGR or grey, not OpenCV type CV_32FC3", JpegError);
  // libjpeg's own error (its longjmp path): wider than JPEG allows.
  CHECK_THROWS_WITH_AS(encoder.encode(cv::Mat(1, 70000, CV_8UC3, cv::Scalar(1, 2, 3)), 80),
                       doctest::Contains("JPEG encoder: Maximum supported image dimension is 65500 pixels"), JpegError);
  const cv::Mat input = jpeg_test_picture(32, 24);
  const cv::Mat output = jpeg_decode(encoder.encode(input, 80), cv::IMREAD_COLOR);
  REQUIRE_FALSE(output.empty());
  CHECK(jpeg_psnr(input, output) > 30.0);
}
