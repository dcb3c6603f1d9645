// The parts of a snapshot camera that need no network: the libjpeg-turbo decoder (what it decodes equals what OpenCV's
// own decoder makes of the same bytes; bad input is a JpegError naming it, after which the decoder still works; a
// header claiming a huge picture is refused before memory is taken) and the URL parser (http only; https refused
// by name; user info, IPv6 and ports); and the source against a camera this test serves (tests/support/
// snapshot_camera.hpp): pass-through, basic auth, and each fault named - 404, not a JPEG, too large, no answer.
#include <doctest/doctest.h>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <string>
#include <vector>

#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include "camera_source.hpp"
#include "jpeg_decoder.hpp"
#include "snapshot_camera.hpp"
#include "snapshot_client.hpp"

using rcand::plugins::vision::CameraFrame;
using rcand::plugins::vision::JpegDecoder;
using rcand::plugins::vision::JpegEncoder;
using rcand::plugins::vision::JpegError;
using rcand::plugins::vision::make_snapshot_source;
using rcand::plugins::vision::parse_snapshot_url;
using rcand::plugins::vision::SourceError;
using rcand::plugins::vision::SourceKind;
using rcand::plugins::vision::SourceSettings;

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

SourceSettings snapshot_settings(const std::string& url) {
  SourceSettings settings;
  settings.kind = SourceKind::Snapshot;
  settings.location = url;
  settings.open_timeout = settings.read_timeout = std::chrono::milliseconds(300);
  settings.snapshot_max_bytes = 64 * 1024;
  return settings;
}

std::string snapshot_open_error(const SourceSettings& settings) {
  try {
    make_snapshot_source(settings)->open();
  } catch (const SourceError& e) {
    return e.what();
  }
  return "no error";
}

}  // namespace

TEST_CASE("snapshot: the source passes the camera's JPEG through, sends basic auth, and names every fault") {
  JpegEncoder encoder;
  const std::string jpeg(encoder.encode(snapshot_test_picture(160, 120), 80));
  rcand::test::SnapshotCamera camera(jpeg);
  const std::string url = camera.url();
  const std::string with_credentials = "http://viewer:s3cret@" + url.substr(7);

  auto source = make_snapshot_source(snapshot_settings(with_credentials));
  CHECK(source->describe() == "snapshot http://***@" + url.substr(7));
  source->open();
  CameraFrame frame;
  for (int i = 0; i < 3; ++i) {
    REQUIRE(source->read_frame(frame));
    REQUIRE(frame.jpeg);
    CHECK(*frame.jpeg == jpeg);  // the camera's own bytes
    CHECK(frame.image.empty());
    CHECK(frame.size == cv::Size(160, 120));
  }
  CHECK(camera.connections() == 1);
  CHECK(camera.last_request().find("\r\nAuthorization: Basic dmlld2VyOnMzY3JldA==") != std::string::npos);

  // The size asked for differs: decoded and scaled.
  auto smaller = snapshot_settings(url);
  smaller.width = 80;
  smaller.height = 60;
  smaller.size_given = true;
  source = make_snapshot_source(smaller);
  source->open();
  REQUIRE(source->read_frame(frame));
  CHECK_FALSE(frame.jpeg);
  CHECK(frame.image.size() == cv::Size(80, 60));

  camera.answer_not_found(true);
  CHECK(snapshot_open_error(snapshot_settings(url)) == "snapshot " + url + ": 404 Not Found");
  camera.answer_not_found(false);

  rcand::test::SnapshotCamera html("<html>it works</html>");
  CHECK(snapshot_open_error(snapshot_settings(html.url())) ==
        "snapshot " + html.url() +
            ": the answer is not a picture rcand can use (JPEG decoder: Not a JPEG file: starts with 0x3c 0x68)");

  rcand::test::SnapshotCamera huge(std::string(100 * 1024, 'x'));
  CHECK(snapshot_open_error(snapshot_settings(huge.url())) ==
        "snapshot " + huge.url() + ": the answer is larger than 64 KiB (snapshot_max_kib)");

  // A camera that takes the connection and never answers: bounded by read_timeout.
  const int silent = ::socket(AF_INET, SOCK_STREAM, 0);
  REQUIRE(silent >= 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  REQUIRE(::bind(silent, reinterpret_cast<sockaddr*>(&address), sizeof address) == 0);
  REQUIRE(::listen(silent, 4) == 0);
  socklen_t length = sizeof address;
  REQUIRE(::getsockname(silent, reinterpret_cast<sockaddr*>(&address), &length) == 0);
  const std::string silent_url = "http://127.0.0.1:" + std::to_string(ntohs(address.sin_port)) + "/snapshot.jpg";
  CHECK(snapshot_open_error(snapshot_settings(silent_url)) == "snapshot " + silent_url + ": no answer within 300 ms");
  ::close(silent);
}

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
