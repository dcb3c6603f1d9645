// The parts of a snapshot camera that need no network: the libjpeg-turbo decoder (what it decodes equals what OpenCV's
// own decoder makes of the same bytes; bad input is a JpegError naming it, after which the decoder still works; a
// header claiming a huge picture is refused before memory is taken) and the URL parser (http only; https refused
// by name; user info, IPv6 and ports).
#include <doctest/doctest.h>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <string>
#include <vector>

#include "jpeg_decoder.hpp"
#include "snapshot_client.hpp"

using rcand::plugins::vision::JpegDecoder;
using rcand::plugins::vision::JpegEncoder;
using rcand::plugins::vision::JpegError;
using rcand::plugins::vision::parse_snapshot_url;

namespace {

cv::Mat snapshot_test_picture(int width, int height) {
  cv::Mat image(height, width, CV_8UC3);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) image.at<cv::Vec3b>(y, x) = cv::Vec3b(static_cast<uchar>(x), static_cast<uchar>(y), 90);
  return image;
}

std::string snapshot_decode_error(JpegDecoder& decoder, const std::string& bytes) {
  try {
    decoder.decode(bytes);
  } catch (const JpegError& e) {
    return e.what();
  }
  return "no error";
}

}  // namespace

TEST_CASE("snapshot: the JPEG decoder reads the size from the header and decodes as OpenCV's decoder does") {
  JpegEncoder encoder;
  JpegDecoder decoder;
  for (const cv::Size size : {cv::Size(160, 120), cv::Size(641, 479), cv::Size(17, 1000)}) {
    const std::string jpeg(encoder.encode(snapshot_test_picture(size.width, size.height), 85));
    CHECK(decoder.size(jpeg) == size);
    const cv::Mat ours = decoder.decode(jpeg);
    const cv::Mat theirs = cv::imdecode(std::vector<uchar>(jpeg.begin(), jpeg.end()), cv::IMREAD_COLOR);
    REQUIRE(ours.type() == CV_8UC3);
    REQUIRE(ours.size() == size);
    CHECK(cv::norm(ours, theirs, cv::NORM_INF) <= 2);  // the same libjpeg; at most IDCT rounding apart
  }
  // A grey picture comes out BGR.
  const cv::Mat grey(48, 64, CV_8UC1, cv::Scalar(77));
  const cv::Mat decoded = decoder.decode(std::string(encoder.encode(grey, 90)));
  REQUIRE(decoded.type() == CV_8UC3);
  CHECK(std::abs(cv::mean(decoded)[0] - 77) < 2);
}

TEST_CASE("snapshot: what is not a usable JPEG is a JpegError in words, and the decoder still works after it") {
  JpegEncoder encoder;
  JpegDecoder decoder;
  const std::string good(encoder.encode(snapshot_test_picture(64, 48), 80));
  CHECK(snapshot_decode_error(decoder, "").find("empty") != std::string::npos);
  CHECK(snapshot_decode_error(decoder, "<html>404</html>").find("JPEG decoder: Not a JPEG file") != std::string::npos);
  CHECK(snapshot_decode_error(decoder, good.substr(0, 40)).find("JPEG decoder:") != std::string::npos);
  // A header that claims 65000x65000: refused from the header, before any pixel memory.
  std::string huge = good;
  const auto sof = huge.find("\xFF\xC0");
  REQUIRE(sof != std::string::npos);
  huge[sof + 5] = huge[sof + 7] = static_cast<char>(0xFD);  // height and width high bytes: 0xFDxx
  CHECK(snapshot_decode_error(decoder, huge).find("larger than 7680x4320") != std::string::npos);
  CHECK(decoder.decode(good).size() == cv::Size(64, 48));
}

TEST_CASE("snapshot: URLs: http with host, port, path, query and credentials; https and others refused by name") {
  std::string error;
  auto url = parse_snapshot_url("http://cam.local/snapshot.jpg", error);
  REQUIRE(url);
  CHECK(url->host == "cam.local");
  CHECK(url->port == 80);
  CHECK(url->target == "/snapshot.jpg");
  url = parse_snapshot_url("http://admin:secret@192.168.1.9:8080/cgi-bin/snap?chn=1&res=hd", error);
  REQUIRE(url);
  CHECK(url->host == "192.168.1.9");
  CHECK(url->port == 8080);
  CHECK(url->userinfo == "admin:secret");
  CHECK(url->target == "/cgi-bin/snap?chn=1&res=hd");
  url = parse_snapshot_url("http://[::1]:81?x=1", error);
  REQUIRE(url);
  CHECK(url->host == "::1");
  CHECK(url->port == 81);
  CHECK(url->target == "/?x=1");
  CHECK(parse_snapshot_url("http://cam", error)->target == "/");

  CHECK_FALSE(parse_snapshot_url("https://cam/snapshot.jpg", error));
  CHECK(error.find("https is not supported") != std::string::npos);
  CHECK_FALSE(parse_snapshot_url("rtsp://cam/stream", error));
  CHECK(error == "expected an http:// URL");
  CHECK_FALSE(parse_snapshot_url("http://cam:99999/x", error));
  CHECK(error.find("port") != std::string::npos);
  CHECK_FALSE(parse_snapshot_url("http:///x.jpg", error));
  CHECK(error.find("no host") != std::string::npos);
  CHECK_FALSE(parse_snapshot_url("http://cam/x.jpg#frag", error));
}
