// vision against a real rcand (docs/protocol.md §7 GET /api/stream/mjpeg): the stream read as a client reads it, every
// JPEG decoded with cv::imdecode; the stream routes behind the same middleware as every other route (bearer or
// ?token=, scopes, 405, 404 for an undeclared vision, rate limits); ?fps= and the viewer limit; viewers capped per
// principal and per address, with places reserved for the operators (issue 28 #8); a stalled viewer beside a reading one; a
// missing camera as a named fault in GET /api/status with a live NO SIGNAL stream.
#include <doctest/doctest.h>

#include <opencv2/imgcodecs.hpp>

#include <thread>

#include "eventually.hpp"
#include "mjpeg_client.hpp"
#include "rcand_process.hpp"

using namespace rcand::test;
using namespace std::chrono_literals;
using nlohmann::json;

namespace {

json vision_config(json camera = {{"type", "synthetic"}, {"resolution", {320, 240}}, {"fps", 30}},
                   json settings = json::object()) {
  auto config = sim_config();
  config["camera"] = std::move(camera);
  config["rcan_protocol"]["capabilities"] = {"status", "teleop", "vision", "com.acme.gripper"};
  if (!settings.empty()) config["runtime"]["capabilities"]["vision"] = std::move(settings);
  return config;
}

cv::Mat decode(const std::string& jpeg) { return cv::imdecode(std::vector<uchar>(jpeg.begin(), jpeg.end()), cv::IMREAD_COLOR); }

// The vision capability's published status in GET /api/status, once `done` holds (bounded: it is published on change
// and about once a second while viewers watch).
template <class Pred> json vision_status(const RcandProcess& rcand, Pred done) {
  const auto deadline = std::chrono::steady_clock::now() + 5s;
  json status;
  do {
    status = rcand.json("GET", "/api/status", "guest-token")["capabilities"]["vision"];
    if (status.contains("status") && done(status["status"])) return status;
    std::this_thread::sleep_for(20ms);  // nothing to wait on from outside: the snapshot is rebuilt every 20 ms at most
  } while (std::chrono::steady_clock::now() < deadline);
  return status;
}

}  // namespace

TEST_CASE("vision: a real rcand streams MJPEG to a client, and every JPEG decodes") {
  RcandProcess rcand(vision_config());
  CHECK(rcand.json("GET", "/api/discovery")["capabilities"] == json{"status", "teleop", "vision", "com.acme.gripper"});
  MjpegClient viewer(rcand.port());
  REQUIRE(viewer.open("/api/stream/mjpeg?token=guest-token") == 200);  // ?token=: what an <img> can send
  CHECK(viewer.header("content-type") == "multipart/x-mixed-replace; boundary=rcandframe");
  CHECK(viewer.header("content-length").empty());
  CHECK(viewer.header("cache-control") == "no-store");
  CHECK_FALSE(viewer.header("x-message-id").empty());

  long last_frame = 0;
  for (int i = 0; i < 45; ++i) {
    auto part = viewer.next_part();
    REQUIRE(part);
    CHECK(part->headers.at("content-type") == "image/jpeg");
    const auto image = decode(part->body);
    REQUIRE_FALSE(image.empty());
    CHECK(image.cols == 320);
    CHECK(image.rows == 240);
    CHECK(part->headers.at("x-signal") == "live");
    const long frame = std::stol(part->headers.at("x-frame"));
    CHECK(frame > last_frame);
    last_frame = frame;
  }

  const auto vision = vision_status(rcand, [](const json& s) { return s["viewers"].size() == 1 && s["captured_fps"] > 0; });
  CHECK(vision["state"] == "ok");
  const auto& status = vision["status"];
  REQUIRE(status["viewers"].size() == 1);
  CHECK(status["viewers"][0]["who"] == "guest-principal");
  CHECK(status["camera"]["state"] == "live");
  CHECK(status["camera"]["source"] == "synthetic 320x240");
  CHECK(status["encoded_fps"] > 0);
}

TEST_CASE("vision: the stream routes pass the same middleware as every route") {
  RcandProcess rcand(vision_config());
  SUBCASE("credentials: none or a wrong one is 401; ?token= only on the stream") {
    MjpegClient none(rcand.port());
    CHECK(none.open("/api/stream/mjpeg") == 401);
    MjpegClient wrong(rcand.port());
    CHECK(wrong.open("/api/stream/mjpeg?token=nope") == 401);
    MjpegClient snapshot_by_query(rcand.port());
    CHECK(snapshot_by_query.open("/api/stream/snapshot?token=guest-token") == 401);
    MjpegClient by_header(rcand.port());
    CHECK(by_header.open("/api/stream/mjpeg", "guest-token") == 200);
  }
  SUBCASE("a snapshot is one JPEG for a guest's bearer token") {
    MjpegClient snapshot(rcand.port());
    REQUIRE(snapshot.open("/api/stream/snapshot", "guest-token") == 200);
    CHECK(snapshot.header("content-type") == "image/jpeg");
    const auto image = decode(snapshot.body());
    CHECK(image.cols == 320);
    CHECK(image.rows == 240);
  }
  SUBCASE("another method is 405 naming GET") {
    int status = 0;
    const auto answer = rcand.json("POST", "/api/stream/mjpeg", "owner-token", "{}", &status);
    CHECK(status == 405);
    CHECK(answer["allowed"] == json{"GET"});
  }
  SUBCASE("bad ?fps= is 400 naming the field") {
    int status = 0;
    const auto answer = rcand.json("GET", "/api/stream/mjpeg?fps=abc", "guest-token", {}, &status);
    CHECK(status == 400);
    CHECK(answer["field"] == "fps");
  }
}

TEST_CASE("vision: an undeclared vision is 404, and the rate limits hold for streams too") {
  SUBCASE("undeclared") {
    RcandProcess rcand(sim_config());
    int status = 0;
    const auto answer = rcand.json("GET", "/api/stream/mjpeg", "guest-token", {}, &status);
    CHECK(status == 404);
    CHECK(answer["code"] == "CAPABILITY_NOT_FOUND");
  }
  SUBCASE("rate limited") {
    auto config = vision_config();
    config["runtime"]["rate_limit"] = {{"per_principal_per_s", 1}, {"per_address_per_s", 0}, {"burst_s", 2}};
    RcandProcess rcand(config);
    MjpegClient a(rcand.port()), b(rcand.port()), c(rcand.port());
    CHECK(a.open("/api/stream/mjpeg", "guest-token") == 200);
    CHECK(b.open("/api/stream/mjpeg", "guest-token") == 200);
    CHECK(c.open("/api/stream/mjpeg", "guest-token") == 429);
    CHECK_FALSE(c.header("retry-after").empty());
  }
}

TEST_CASE("vision: the viewer limit is 503 naming it, and a place frees when a viewer leaves") {
  RcandProcess rcand(vision_config(json{{"type", "synthetic"}, {"resolution", {160, 120}}}, {{"max_viewers", 2}}));
  auto a = std::make_unique<MjpegClient>(rcand.port());
  MjpegClient b(rcand.port()), c(rcand.port());
  REQUIRE(a->open("/api/stream/mjpeg", "owner-token") == 200);  // the owner: the reserved place is one of the two
  REQUIRE(b.open("/api/stream/mjpeg", "owner-token") == 200);
  REQUIRE(c.open("/api/stream/mjpeg", "owner-token") == 503);
  CHECK(c.header("retry-after") == "5");
  const auto refusal = json::parse(c.body());
  CHECK(refusal["limit"] == 2);
  CHECK(refusal["code"] == "UNAVAILABLE");
  a.reset();  // the client leaves: its place is free once rcand has seen the close
  const auto deadline = std::chrono::steady_clock::now() + 5s;
  int status = 0;
  while (status != 200 && std::chrono::steady_clock::now() < deadline) {
    MjpegClient d(rcand.port());
    status = d.open("/api/stream/mjpeg", "owner-token");
    if (status == 200) REQUIRE(d.next_part());
    else std::this_thread::sleep_for(20ms);
  }
  CHECK(status == 200);
}

TEST_CASE("vision: 200 viewers at once: the first max_viewers stream live, the rest get 503, the stop still answers") {
  RcandProcess rcand(vision_config(json{{"type", "synthetic"}, {"resolution", {160, 120}}, {"fps", 30}}));
  std::vector<std::unique_ptr<MjpegClient>> viewers;
  int streaming = 0, refused = 0;
  for (int i = 0; i < 200; ++i) {  // as the OWNER: a principal below holds a few viewers at most (next test)
    viewers.push_back(std::make_unique<MjpegClient>(rcand.port()));
    const int status = viewers.back()->open("/api/stream/mjpeg", "owner-token");
    if (status == 200) ++streaming;
    else if (status == 503) ++refused;
  }
  CHECK(streaming == 32);  // the default max_viewers
  CHECK(refused == 168);
  for (auto& viewer : viewers)  // every accepted viewer gets live frames while the others were being refused
    if (viewer->status() == 200) CHECK(viewer->next_part());
  int status = 0;
  rcand.json("POST", "/api/stop", "guest-token", "{}", &status);
  CHECK(status == 200);
}

TEST_CASE("vision: a GUEST's viewers at ?fps=0.001 cannot lock the owner's dashboard out of the camera") {
  // Issue 28 #8: 32 guest viewers at ?fps=0.001 used to hold every place, and the owner got 503.
  auto config =
      vision_config(json{{"type", "synthetic"}, {"resolution", {160, 120}}}, {{"max_viewers", 6}, {"reserved_viewers", 2}});
  config["runtime"]["max_streams_per_principal"] = 3;
  config["runtime"]["max_streams_per_address"] = 100;
  RcandProcess rcand(config);
  int status = 0;
  auto answer = rcand.json("GET", "/api/stream/mjpeg?fps=0.001", "guest-token", {}, &status);
  CHECK(status == 400);  // would be offered no frame for 10 s, and cut: refused at once instead
  CHECK(answer["field"] == "fps");

  std::vector<std::unique_ptr<MjpegClient>> viewers;
  auto open = [&](const std::string& token, const std::string& fps = "1") {
    viewers.push_back(std::make_unique<MjpegClient>(rcand.port()));
    return viewers.back()->open("/api/stream/mjpeg?fps=" + fps, token);
  };
  int guests = 0;
  for (int i = 0; i < 6; ++i) guests += open("guest-token", "0.2") == 200 ? 1 : 0;
  CHECK(guests == 3);  // was 6: and then the owner's dashboard got 503
  CHECK(open("guest-token") == 429);
  const std::string refused = viewers.back()->body();
  INFO(refused);
  CHECK(json::parse(refused, nullptr, false).value("code", "") == "TOO_MANY_STREAMS");
  CHECK_FALSE(viewers.back()->header("retry-after").empty());

  CHECK(open("user-token") == 200);  // 4 of 6: the last 2 are the operators'
  CHECK(open("user-token") == 503);
  CHECK(json::parse(viewers.back()->body(), nullptr, false).value("code", "") == "SLOTS_RESERVED");
  CHECK(open("owner-token") == 200);
  REQUIRE(viewers.back()->next_part());  // the owner's dashboard shows the camera
  CHECK(open("owner-token") == 200);
  CHECK(open("owner-token") == 503);  // max_viewers holds for everyone
}

TEST_CASE("vision: viewers of many principals on one address share its cap; OWNER is not counted against it") {
  auto config = vision_config(json{{"type", "synthetic"}, {"resolution", {160, 120}}});
  config["runtime"]["max_streams_per_principal"] = 3;
  config["runtime"]["max_streams_per_address"] = 4;
  RcandProcess rcand(config);
  std::vector<std::unique_ptr<MjpegClient>> viewers;
  auto open = [&](const std::string& token) {
    viewers.push_back(std::make_unique<MjpegClient>(rcand.port()));
    return viewers.back()->open("/api/stream/mjpeg", token);
  };
  for (int i = 0; i < 3; ++i) CHECK(open("guest-token") == 200);
  CHECK(open("user-token") == 200);
  CHECK(open("user-token") == 429);  // the user's own cap has room; the address's not
  const std::string refused = viewers.back()->body();
  INFO(refused);
  CHECK(json::parse(refused, nullptr, false).value("error", "").find("address 127.0.0.1") != std::string::npos);
  CHECK(open("owner-token") == 200);
  // A viewer that leaves gives its place back.
  viewers.front().reset();
  const auto deadline = std::chrono::steady_clock::now() + 5s;
  int status = 0;
  while (status != 200 && std::chrono::steady_clock::now() < deadline) {
    status = open("guest-token");
    if (status != 200) std::this_thread::sleep_for(20ms);  // until rcand has seen the close: no event to wait on
  }
  CHECK(status == 200);
}

TEST_CASE("vision: a viewer that never reads does not lower another's frame rate") {
  RcandProcess rcand(vision_config(json{{"type", "synthetic"}, {"resolution", {640, 480}}, {"fps", 30}}));
  MjpegClient stalled(rcand.port(), 4096);
  REQUIRE(stalled.open("/api/stream/mjpeg", "guest-token") == 200);  // and never reads again
  MjpegClient reader(rcand.port());
  REQUIRE(reader.open("/api/stream/mjpeg", "user-token") == 200);
  REQUIRE(reader.next_part());
  // Against the frames the camera captured meanwhile, not an absolute rate: a loaded machine slows the camera and
  // the reader alike, while a hub held up by the stalled viewer would starve the reader alone.
  const auto captured = [&] {
    return rcand.json("GET", "/api/status", "guest-token")["capabilities"]["vision"]["status"]["frames_captured"].get<long>();
  };
  const long captured_before = captured();
  const auto started = std::chrono::steady_clock::now();
  int frames = 0;
  while (std::chrono::steady_clock::now() - started < 3s) {
    auto part = reader.next_part();
    REQUIRE(part);
    CHECK_FALSE(decode(part->body).empty());
    ++frames;
  }
  const long captured_during = captured() - captured_before;
  MESSAGE("reader frames beside a stalled viewer: " << frames << " of " << captured_during << " captured");
  REQUIRE(captured_during >= 30);  // the camera ran (about 90 frames in 3 s unloaded)
  CHECK(frames >= 0.8 * static_cast<double>(captured_during));
  const auto status = vision_status(rcand, [](const json& s) { return s["viewers"].size() == 2; });
  CHECK(status["status"]["viewers"].size() == 2);
}

TEST_CASE("vision: a missing camera is a named fault in /api/status, and the stream is live NO SIGNAL frames") {
  RcandProcess rcand(vision_config(json{{"type", "usb"}, {"device", "/dev/video97"}}));
  MjpegClient viewer(rcand.port());
  REQUIRE(viewer.open("/api/stream/mjpeg?token=guest-token") == 200);
  for (int i = 0; i < 3; ++i) {
    auto part = viewer.next_part();
    REQUIRE(part);
    CHECK(part->headers.at("x-signal") == "none");
    const auto image = decode(part->body);
    CHECK(image.cols == 640);
    CHECK(image.rows == 480);
  }
  const auto vision = vision_status(rcand, [](const json& s) { return s["camera"]["state"] == "no_signal"; });
  CHECK(vision["state"] == "error");  // the capability runs, but shows no picture: never "ok" (issue 28 item 4)
  CHECK(vision["reason"] == "camera device /dev/video97 does not exist");
  CHECK(vision["status"]["camera"]["fault"] == "camera device /dev/video97 does not exist");
  CHECK(vision["status"]["camera"]["source"] == "v4l2 /dev/video97");
  CHECK(count_of(rcand.stderr_text(), "camera device /dev/video97 does not exist") >= 1);
}

TEST_CASE("vision depth: the synthetic scene's zones, the depth frame, and nav stopped by its obstacle with the motors at zero") {
  auto config = vision_config(json{{"type", "synthetic"}, {"resolution", {160, 120}}, {"depth", "synthetic"}});
  config["rcan_protocol"]["capabilities"] = {"status", "teleop", "nav", "vision"};
  config["agent"] = {{"min_obstacle_m", 0.5}};
  RcandProcess rcand(config);

  // The scene's own objects never come nearer than 1 m; the test places one itself once the job runs.
  const auto deadline = std::chrono::steady_clock::now() + 5s;
  json zones;
  do {
    zones = rcand.json("GET", "/api/depth/obstacles", "guest-token");
    if (zones["available"] == true) break;
    std::this_thread::sleep_for(20ms);
  } while (std::chrono::steady_clock::now() < deadline);
  REQUIRE(zones["available"] == true);
  CHECK(zones["nearest_cm"] >= 100);
  for (const char* key : {"left_cm", "center_cm", "right_cm", "nearest_cm", "timestamp_ms"}) CHECK(zones.contains(key));
  CHECK(zones["nearest_cm"] ==
        std::min({zones["left_cm"].get<double>(), zones["center_cm"].get<double>(), zones["right_cm"].get<double>()}));

  MjpegClient frame(rcand.port());
  REQUIRE(frame.open("/api/depth/frame", "guest-token") == 200);
  CHECK(frame.header("content-type") == "image/jpeg");
  CHECK(decode(frame.body()).cols == 640);

  // 2 m at speed 0.2: 47 s of driving, unless an object comes within 50 cm first (nav checks every 25 ms). With vision
  // in a process of its own (RCAND_TEST_ISOLATE), nav's copy of the zones follows vision's by up to one poll of the
  // host (10 ms): "depth unavailable" until it has the first one.
  int status = 0;
  json answer;
  REQUIRE(eventually(
      [&] {
        answer = rcand.json("POST", "/api/nav/waypoint", "user-token",
                            json{{"distance_m", 2.0}, {"heading_deg", 0}, {"speed", 0.2}}.dump(), &status);
        return status != 503 || answer.value("reason", "") != "depth_unavailable";
      },
      2s));
  INFO(answer.dump());
  REQUIRE(status == 200);
  CHECK(answer["ok"] == true);
  std::this_thread::sleep_for(200ms);
  const auto placed =
      rcand.json("POST", "/api/depth/sim_obstacle", "user-token", json{{"zone", "center"}, {"distance_m", 0.25}}.dump(), &status);
  REQUIRE(status == 200);
  CHECK(placed["obstacles"]["center_cm"] == 25);
  json nav;
  const auto job_deadline = std::chrono::steady_clock::now() + 20s;
  do {
    nav = rcand.json("GET", "/api/nav/status", "guest-token");
    if (nav["running"] == false) break;
    std::this_thread::sleep_for(20ms);
  } while (std::chrono::steady_clock::now() < job_deadline);
  REQUIRE(nav["running"] == false);
  CHECK(nav["result"]["reason"] == "obstacle");
  const auto estop = rcand.json("GET", "/api/estop", "guest-token");
  CHECK(estop["estopped"] == true);
  CHECK(estop["reason"].get<std::string>().find("[depth available=true left_cm=") != std::string::npos);
  CHECK(estop["reason"].get<std::string>().find("center_cm=25.0") != std::string::npos);
  const auto drive = drive_status(rcand);
  CHECK(drive["moving"] == false);
  REQUIRE_FALSE(drive["timeline"].empty());
  CHECK(drive["timeline"].back()["left"] == 0.0);
  CHECK(drive["timeline"].back()["right"] == 0.0);
}
