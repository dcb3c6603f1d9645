// An HTTP snapshot camera end to end (issue 30 item 3): a real rcand polls a URL that the test serves on a loopback
// port of its own (one JPEG per GET, HTTP/1.1 keep-alive) and streams it as MJPEG. Frames of the size asked for (or
// with no size asked for) reach viewers byte for byte as the camera served them, on one kept-alive connection; a
// size that differs is decoded, scaled and re-encoded. A camera that answers 404, or goes away, is NO SIGNAL on the
// stream and vision "error" in GET /api/status with the named fault, until it answers again.
#include <doctest/doctest.h>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <vector>

#include "eventually.hpp"
#include "mjpeg_client.hpp"
#include "rcand_process.hpp"
#include "snapshot_camera.hpp"

using namespace rcand::test;
using namespace std::chrono_literals;
using nlohmann::json;

namespace {

std::string snapshot_jpeg(int width, int height, cv::Scalar colour) {
  std::vector<uchar> jpeg;
  REQUIRE(cv::imencode(".jpg", cv::Mat(height, width, CV_8UC3, colour), jpeg));
  return {jpeg.begin(), jpeg.end()};
}

json snapshot_camera_config(json camera) {
  auto config = sim_config();
  config["camera"] = std::move(camera);
  config["rcan_protocol"]["capabilities"] = {"status", "teleop", "vision"};
  config["runtime"]["capabilities"]["vision"] = {{"reconnect_max_ms", 500}};
  return config;
}

// Reads parts until one whose X-Signal is `signal` (bounded: at most `parts` parts, each within 5 s).
std::optional<MjpegClient::Part> snapshot_part_with_signal(MjpegClient& viewer, const std::string& signal, int parts = 400) {
  for (int i = 0; i < parts; ++i) {
    auto part = viewer.next_part();
    if (!part) return std::nullopt;
    if (part->headers.at("x-signal") == signal) return part;
  }
  return std::nullopt;
}

cv::Mat snapshot_decoded(const MjpegClient::Part& part) {
  return cv::imdecode(std::vector<uchar>(part.body.begin(), part.body.end()), cv::IMREAD_COLOR);
}

json snapshot_vision(const RcandProcess& rcand) {
  return rcand.json("GET", "/api/status", "guest-token")["capabilities"]["vision"];
}

}  // namespace

TEST_CASE("vision: a snapshot camera's JPEGs stream as they are; 404 or gone is NO SIGNAL and a named error until it answers") {
  const std::string jpeg = snapshot_jpeg(160, 120, cv::Scalar(0, 200, 0));
  std::optional<SnapshotCamera> camera(std::in_place, jpeg);
  const std::string url = camera->url();
  const std::uint16_t port = camera->port();
  RcandProcess rcand(snapshot_camera_config({{"type", "snapshot"}, {"url", url}, {"fps", 20}}));
  MjpegClient viewer(rcand.port());
  REQUIRE(viewer.open("/api/stream/mjpeg?token=guest-token") == 200);

  // Live frames are the camera's own bytes: passed through, neither decoded nor re-encoded.
  for (int i = 0; i < 5; ++i) {
    const auto live = snapshot_part_with_signal(viewer, "live");
    REQUIRE(live);
    CHECK(live->body == jpeg);
  }
  REQUIRE(eventually([&] { return snapshot_vision(rcand)["state"] == "ok"; }, 10s));
  CHECK(snapshot_vision(rcand)["status"]["camera"]["source"] == "snapshot " + url);
  // The status is published about once a second while viewers watch.
  CHECK(eventually([&] { return snapshot_vision(rcand)["status"]["frames_passed_through"].get<int>() >= 5; }, 10s));
  CHECK(eventually(
      [&] {
        return rcand.request("GET", "/metrics", "guest-token")
                   .body.find("rcand_vision_frames_per_second{stage=\"passed_through\"} 0\n") == std::string::npos;
      },
      10s));
  CHECK(camera->requests() >= 5);
  CHECK(camera->connections() == 1);  // every request on the one kept-alive connection

  // 404: NO SIGNAL on the stream, and the fault with the status in GET /api/status.
  camera->answer_not_found(true);
  const auto stale = snapshot_part_with_signal(viewer, "none");
  REQUIRE(stale);
  CHECK(cv::mean(snapshot_decoded(*stale))[1] < 100);  // the dark NO SIGNAL frame, not the green picture
  REQUIRE(eventually([&] { return snapshot_vision(rcand)["state"] == "error"; }, 10s));
  CHECK(snapshot_vision(rcand)["reason"] == "snapshot " + url + ": 404 Not Found");
  CHECK(rcand.json("GET", "/api/status", "guest-token")["state"] == "error");

  camera->answer_not_found(false);
  const auto back = snapshot_part_with_signal(viewer, "live");
  REQUIRE(back);
  CHECK(back->body == jpeg);
  REQUIRE(eventually([&] { return snapshot_vision(rcand)["state"] == "ok"; }, 10s));

  // Gone (nothing listens on its port): the connect error, named; then back on the same port.
  camera.reset();
  REQUIRE(snapshot_part_with_signal(viewer, "none"));
  REQUIRE(eventually([&] { return snapshot_vision(rcand)["state"] == "error"; }, 10s));
  CHECK(snapshot_vision(rcand)["reason"] ==
        "snapshot " + url + ": cannot connect to 127.0.0.1:" + std::to_string(port) + ": Connection refused");
  camera.emplace(jpeg, port);
  const auto again = snapshot_part_with_signal(viewer, "live");
  REQUIRE(again);
  CHECK(again->body == jpeg);
  REQUIRE(eventually([&] { return snapshot_vision(rcand)["state"] == "ok"; }, 10s));
  CHECK_FALSE(snapshot_vision(rcand).contains("reason"));
}

TEST_CASE("vision: a snapshot camera whose picture is not the size asked for is decoded, scaled and re-encoded") {
  const std::string jpeg = snapshot_jpeg(160, 120, cv::Scalar(0, 200, 0));
  SnapshotCamera camera(jpeg);
  RcandProcess rcand(
      snapshot_camera_config({{"type", "snapshot"}, {"url", camera.url()}, {"resolution", {80, 60}}, {"fps", 20}}));
  MjpegClient viewer(rcand.port());
  REQUIRE(viewer.open("/api/stream/mjpeg?token=guest-token") == 200);
  const auto live = snapshot_part_with_signal(viewer, "live");
  REQUIRE(live);
  CHECK(live->body != jpeg);
  const cv::Mat picture = snapshot_decoded(*live);
  REQUIRE_FALSE(picture.empty());
  CHECK(picture.size() == cv::Size(80, 60));
  CHECK(cv::mean(picture)[1] > 150);  // the camera's green
  CHECK(snapshot_vision(rcand)["status"]["frames_passed_through"] == 0);
}
