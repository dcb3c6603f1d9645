// The vision plugin's stream metrics (issue 18) on a real rcand: an MJPEG viewer shows in rcand_vision_stream_viewers
// while it watches and leaves it when it closes, with the frame rates beside it; the page stays promtool-clean.
#include <doctest/doctest.h>

#include <chrono>
#include <functional>
#include <iostream>
#include <thread>

#include "mjpeg_client.hpp"
#include "promtool.hpp"
#include "rcand_process.hpp"

using namespace rcand::test;
using nlohmann::json;

namespace {

// GET /metrics until `holds(page)`, for at most 5 s: the plugin records when its frame hub publishes its status (on
// every change, at most 10 times a second), which nothing outside the process can wait on.
std::string metrics_once(const RcandProcess& robot, const std::function<bool(const std::string&)>& holds) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  std::string page;
  do {
    page = robot.request("GET", "/metrics", "guest-token").body;
    if (holds(page)) return page;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  } while (std::chrono::steady_clock::now() < deadline);
  return page;
}

bool has_line(const std::string& page, const std::string& line) { return page.find("\n" + line + "\n") != std::string::npos; }

}  // namespace

TEST_CASE("vision metrics: a viewer shows in the viewers gauge while it watches, with the frame rates") {
  auto config = sim_config();
  config["camera"] = {{"type", "synthetic"}, {"resolution", {160, 120}}, {"fps", 30}};
  config["rcan_protocol"]["capabilities"] = {"status", "teleop", "vision", "com.acme.gripper"};
  RcandProcess robot(config);
  CHECK(has_line(robot.request("GET", "/metrics", "guest-token").body, "rcand_vision_stream_viewers 0"));

  std::string page;
  {
    MjpegClient viewer(robot.port());
    REQUIRE(viewer.open("/api/stream/mjpeg?token=guest-token") == 200);
    REQUIRE(viewer.next_part());
    page = metrics_once(robot, [](const std::string& p) { return has_line(p, "rcand_vision_stream_viewers 1"); });
    CHECK(has_line(page, "rcand_vision_stream_viewers 1"));
    page = metrics_once(robot, [](const std::string& p) {
      return p.find("rcand_vision_frames_per_second{stage=\"encoded\"} 0\n") == std::string::npos;
    });
    CHECK(page.find("rcand_vision_frames_per_second{stage=\"captured\"} ") != std::string::npos);
    CHECK(page.find("rcand_vision_frames_per_second{stage=\"encoded\"} 0\n") == std::string::npos);  // frames flow
  }
  const std::string after =
      metrics_once(robot, [](const std::string& p) { return has_line(p, "rcand_vision_stream_viewers 0"); });
  CHECK(has_line(after, "rcand_vision_stream_viewers 0"));

  rcand::test::check_promtool_clean(page);
}
