// An HTTP snapshot camera end to end (issue 30 item 3): a real rcand polls a URL that the test serves on a loopback
// port of its own (one JPEG per GET, HTTP/1.1 keep-alive) and streams it as MJPEG. Frames of the size asked for (or
// with no size asked for) reach viewers byte for byte as the camera served them, on one kept-alive connection; a
// size that differs is decoded, scaled and re-encoded. A camera that answers 404, or goes away, is NO SIGNAL on the
// stream and vision "error" in GET /api/status with the named fault, until it answers again.
#include <doctest/doctest.h>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <mutex>
#include <thread>
#include <vector>

#include "eventually.hpp"
#include "mjpeg_client.hpp"
#include "rcand_process.hpp"

using namespace rcand::test;
using namespace std::chrono_literals;
using nlohmann::json;

namespace {

// A snapshot camera on 127.0.0.1: every GET is answered with `jpeg` (200) or 404, on a kept-alive connection. Made
// on a given port, it binds that one (SO_REUSEADDR): the camera that went away comes back where it was.
class SnapshotCamera {
 public:
  SnapshotCamera(std::string jpeg, std::uint16_t port = 0) : jpeg_(std::move(jpeg)) {
    listener_ = ::socket(AF_INET, SOCK_STREAM, 0);
    REQUIRE(listener_ >= 0);
    const int yes = 1;
    ::setsockopt(listener_, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_port = htons(port);
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    REQUIRE(::bind(listener_, reinterpret_cast<sockaddr*>(&address), sizeof address) == 0);
    REQUIRE(::listen(listener_, 8) == 0);
    socklen_t length = sizeof address;
    REQUIRE(::getsockname(listener_, reinterpret_cast<sockaddr*>(&address), &length) == 0);
    port_ = ntohs(address.sin_port);
    acceptor_ = std::thread([this] { accept_loop(); });
  }
  ~SnapshotCamera() {
    {
      std::lock_guard lock(mutex_);
      stopping_ = true;
      for (int fd : clients_) ::shutdown(fd, SHUT_RDWR);
    }
    ::shutdown(listener_, SHUT_RDWR);  // wakes accept()
    acceptor_.join();
    for (auto& server : servers_) server.join();
    ::close(listener_);
  }

  std::uint16_t port() const { return port_; }
  std::string url() const { return "http://127.0.0.1:" + std::to_string(port_) + "/snapshot.jpg"; }
  void answer_not_found(bool not_found) { not_found_ = not_found; }
  int connections() const { return connections_; }
  int requests() const { return requests_; }

 private:
  void accept_loop() {
    while (true) {
      const int fd = ::accept(listener_, nullptr, nullptr);
      std::lock_guard lock(mutex_);
      if (fd < 0 || stopping_) {
        if (fd >= 0) ::close(fd);
        return;
      }
      ++connections_;
      clients_.push_back(fd);
      servers_.emplace_back([this, fd] { serve(fd); });
    }
  }

  // Request after request on one connection, until the client or the destructor closes it.
  void serve(int fd) {
    std::string pending;
    char buffer[2048];
    while (true) {
      const auto end = pending.find("\r\n\r\n");
      if (end == std::string::npos) {
        const ssize_t got = ::recv(fd, buffer, sizeof buffer, 0);
        if (got <= 0) break;
        pending.append(buffer, static_cast<std::size_t>(got));
        continue;
      }
      const bool get = pending.starts_with("GET /snapshot.jpg HTTP/1.1\r\n");
      pending.erase(0, end + 4);
      ++requests_;
      const std::string answer =
          !get || not_found_
              ? std::string("HTTP/1.1 404 Not Found\r\nContent-Type: text/plain\r\nContent-Length: 9\r\n\r\nnot found")
              : "HTTP/1.1 200 OK\r\nContent-Type: image/jpeg\r\nContent-Length: " + std::to_string(jpeg_.size()) + "\r\n\r\n" +
                    jpeg_;
      if (::send(fd, answer.data(), answer.size(), MSG_NOSIGNAL) != static_cast<ssize_t>(answer.size())) break;
    }
    ::close(fd);  // after the destructor's shutdown(): the descriptor is not reused before it
  }

  std::string jpeg_;
  int listener_ = -1;
  std::uint16_t port_ = 0;
  std::atomic<bool> not_found_{false};
  std::atomic<int> connections_{0}, requests_{0};
  std::thread acceptor_;
  std::mutex mutex_;
  bool stopping_ = false;
  std::vector<int> clients_;
  std::vector<std::thread> servers_;
};

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
