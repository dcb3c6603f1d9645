// The vision benchmark (issue 15): an rcand with the bundled sim robot's synthetic camera (640x480 at 30 fps) streams
// GET /api/stream/mjpeg to N local viewers (default 20), each a thread reading the multipart stream like a browser.
// Reported:
//  - each viewer's frame rate over the window;
//  - rcand's CPU (utime + stime from /proc/<pid>/stat) as % of one core, idle (nobody watching) and streaming;
//  - capture -> client latency: the part's X-Timestamp-Us (rcand's steady clock when the frame was captured) to the
//    moment the viewer holds the whole part (this machine's steady clock: the same CLOCK_MONOTONIC). It includes the
//    encode, the socket and the viewer thread's own wake-up, so it bounds capture -> socket from above;
//  - frames encoded per second against frames captured (encode once: equal, whatever the number of viewers), and
//    rcand's CPU per captured frame (streaming CPU / captured fps);
//  - POST /api/stop round trips (each latches, then is cleared), with nobody watching and then while the viewers
//    stream, after the measuring window (the e-stop path must not notice the streams).
// --source snapshot: the camera is an HTTP snapshot camera this process serves on loopback (tests/support/
// snapshot_camera.hpp), one JPEG of the test pattern at W x H, polled by rcand at F; its JPEG passes through to viewers
// (no decode, no encode). --source snapshot-resize asks rcand for half that size: every frame decoded, scaled and
// re-encoded. The default, --source synthetic, draws and encodes every frame.
//   bench_vision [--source synthetic|snapshot|snapshot-resize] [--viewers N] [--seconds S] [--idle-seconds S]
//                [--width W] [--height H] [--fps F]
#include <nlohmann/json.hpp>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <fstream>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "mjpeg_client.hpp"
#include "rcand_process.hpp"
#include "snapshot_camera.hpp"

namespace {

// Eight colour bars over a smooth gradient: about what a camera's picture costs to decode and encode.
void draw_bench_pattern(cv::Mat& picture) {
  for (int y = 0; y < picture.rows; ++y)
    for (int x = 0; x < picture.cols; ++x) {
      const int bar = x * 8 / picture.cols;
      picture.at<cv::Vec3b>(y, x) =
          cv::Vec3b(static_cast<uchar>((bar & 1) * 150 + y % 64), static_cast<uchar>((bar & 2) * 75 + x % 48),
                    static_cast<uchar>((bar & 4) * 37 + (x + y) % 80));
    }
}

using nlohmann::json;
using Clock = std::chrono::steady_clock;

double percentile(std::vector<double> values, double p) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  return values[static_cast<std::size_t>(p * static_cast<double>(values.size() - 1))];
}

// utime + stime of `pid`, in clock ticks.
long cpu_ticks(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::istringstream fields(text.substr(text.rfind(')') + 2));
  std::string field;
  long utime = 0, stime = 0;
  for (int i = 3; fields >> field; ++i) {
    if (i == 14) utime = std::stol(field);
    if (i == 15) {
      stime = std::stol(field);
      break;
    }
  }
  return utime + stime;
}

// rcand's CPU over `seconds`, in % of one core.
// VmRSS of `pid`, in kB (0 when it cannot be read).
long resident_kb(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  for (std::string line; std::getline(in, line);)
    if (line.rfind("VmRSS:", 0) == 0) return std::stol(line.substr(6));
  return 0;
}

double cpu_percent(pid_t pid, double seconds) {
  const long before = cpu_ticks(pid);
  const auto started = Clock::now();
  std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
  const double elapsed = std::chrono::duration<double>(Clock::now() - started).count();
  return 100.0 * static_cast<double>(cpu_ticks(pid) - before) / static_cast<double>(::sysconf(_SC_CLK_TCK)) / elapsed;
}

struct Viewer {
  std::atomic<long> frames{0};
  long frames_at_start = 0, frames_at_end = 0;
  std::vector<double> latency_ms;  // only inside the window
  std::mutex mutex;
  bool failed = false;
};

// POST /api/stop round trips for `seconds`, one every 50 ms, each latching (and cleared again).
std::vector<double> stop_round_trips(std::uint16_t port, double seconds) {
  std::vector<double> ms;
  rcand::http::Client client("127.0.0.1", port);
  const std::map<std::string, std::string> owner{{"Authorization", "Bearer owner-token"}};
  const auto started = Clock::now();
  while (Clock::now() - started < std::chrono::duration<double>(seconds)) {
    const auto before = Clock::now();
    const auto answer = client.request("POST", "/api/stop", "", owner);
    ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - before).count());
    if (answer.status != 200) throw std::runtime_error("POST /api/stop answered " + std::to_string(answer.status));
    client.request("POST", "/api/estop/clear", "", owner);
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return ms;
}

struct Options {
  int viewers = 20;
  double seconds = 20, idle_seconds = 5;
  int width = 640, height = 480;
  double fps = 30;
  std::string source = "synthetic";
  bool isolated = false;  // --isolated 1: vision in a process of its own (issue 34); CPU and memory of both processes
};

Options parse(int argc, char** argv) {
  Options o;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string key = argv[i];
    if (key == "--source") {
      o.source = argv[i + 1];
      if (o.source != "synthetic" && o.source != "snapshot" && o.source != "snapshot-resize")
        throw std::runtime_error("--source: synthetic, snapshot or snapshot-resize");
      continue;
    }
    const double value = std::stod(argv[i + 1]);
    if (key == "--viewers") o.viewers = static_cast<int>(value);
    else if (key == "--seconds") o.seconds = value;
    else if (key == "--idle-seconds") o.idle_seconds = value;
    else if (key == "--width") o.width = static_cast<int>(value);
    else if (key == "--height") o.height = static_cast<int>(value);
    else if (key == "--fps") o.fps = value;
    else if (key == "--isolated") o.isolated = value != 0;
    else throw std::runtime_error("unknown option " + key);
  }
  return o;
}

}  // namespace

int main(int argc, char** argv) try {
  const Options o = parse(argc, argv);
  auto config = rcand::test::sim_config();
  config["camera"] = {{"type", "synthetic"}, {"resolution", {o.width, o.height}}, {"fps", o.fps}};
  std::optional<rcand::test::SnapshotCamera> camera;
  if (o.source != "synthetic") {
    // The synthetic camera's test pattern, as a camera would serve it.
    cv::Mat picture(o.height, o.width, CV_8UC3);
    draw_bench_pattern(picture);
    std::vector<uchar> jpeg;
    cv::imencode(".jpg", picture, jpeg, {cv::IMWRITE_JPEG_QUALITY, 80});
    camera.emplace(std::string(jpeg.begin(), jpeg.end()));
    config["camera"] = {{"type", "snapshot"}, {"url", camera->url()}, {"fps", o.fps}};
    if (o.source == "snapshot-resize") config["camera"]["resolution"] = {o.width / 2, o.height / 2};
  }
  config["rcan_protocol"]["capabilities"] = {"status", "teleop", "vision", "com.acme.gripper"};
  config["runtime"]["capabilities"]["vision"] = {{"max_viewers", std::max(32, o.viewers)}};
  if (o.isolated) config["runtime"]["capabilities"]["vision"]["isolation"] = "process";
  config["runtime"]["logging"]["level"] = "warn";
  rcand::test::RcandProcess rcand(config);
  std::printf("rcand pid %d on port %u: %s %dx%d at %.0f fps, %d viewers, %.0f s\n", rcand.pid(), rcand.port(), o.source.c_str(),
              o.width, o.height, o.fps, o.viewers, o.seconds);

  std::this_thread::sleep_for(std::chrono::seconds(1));  // startup settled
  // With --isolated, the host process that runs vision (its pid in vision's status) is measured beside rcand.
  const json process = rcand.json("GET", "/api/status", "guest-token")["capabilities"]["vision"]["status"]["process"];
  const pid_t host = process.is_object() ? process["pid"].get<pid_t>() : 0;
  if (o.isolated && host == 0) throw std::runtime_error("--isolated: vision's status names no process");
  const auto both_ticks = [&] { return cpu_ticks(rcand.pid()) + (host != 0 ? cpu_ticks(host) : 0); };
  const long idle_host_before = host != 0 ? cpu_ticks(host) : 0;
  const double idle_cpu = cpu_percent(rcand.pid(), o.idle_seconds);
  const double idle_host_cpu = host != 0 ? 100.0 * static_cast<double>(cpu_ticks(host) - idle_host_before) /
                                               static_cast<double>(::sysconf(_SC_CLK_TCK)) / o.idle_seconds
                                         : 0.0;
  const auto idle_stops = stop_round_trips(rcand.port(), o.idle_seconds);

  std::vector<std::unique_ptr<Viewer>> viewers;
  std::vector<std::thread> threads;
  std::atomic<bool> measuring{false}, stopping{false};
  for (int i = 0; i < o.viewers; ++i) {
    auto& viewer = *viewers.emplace_back(std::make_unique<Viewer>());
    threads.emplace_back([&, port = rcand.port()] {
      rcand::test::MjpegClient client(port);
      // As the OWNER: a principal below holds 4 viewers at most (runtime.max_streams_per_principal).
      if (client.open("/api/stream/mjpeg?token=owner-token") != 200) {
        viewer.failed = true;
        return;
      }
      while (!stopping) {
        auto part = client.next_part(std::chrono::seconds(5));
        if (!part) {
          viewer.failed = true;
          return;
        }
        ++viewer.frames;
        if (!measuring) continue;
        const auto captured_us = std::stoll(part->headers.at("x-timestamp-us"));
        const auto received_us = std::chrono::duration_cast<std::chrono::microseconds>(part->received.time_since_epoch()).count();
        std::lock_guard lock(viewer.mutex);
        viewer.latency_ms.push_back(static_cast<double>(received_us - captured_us) / 1000.0);
      }
    });
  }
  std::this_thread::sleep_for(std::chrono::seconds(2));  // every viewer connected and streaming

  auto vision_status = [&] { return rcand.json("GET", "/api/status", "guest-token")["capabilities"]["vision"]["status"]; };
  const json status_before = vision_status();
  for (auto& viewer : viewers) viewer->frames_at_start = viewer->frames;
  measuring = true;
  const auto window_start = Clock::now();
  const long ticks_before = cpu_ticks(rcand.pid()), both_before = both_ticks();

  std::this_thread::sleep_for(std::chrono::duration<double>(o.seconds));
  const long ticks_after = cpu_ticks(rcand.pid()), both_after = both_ticks();
  const long rss_kb = resident_kb(rcand.pid()), host_rss_kb = host != 0 ? resident_kb(host) : 0;
  measuring = false;
  const double window = std::chrono::duration<double>(Clock::now() - window_start).count();
  for (auto& viewer : viewers) viewer->frames_at_end = viewer->frames;
  const json status_after = vision_status();
  const auto streaming_stops = stop_round_trips(rcand.port(), o.idle_seconds);
  stopping = true;
  for (auto& thread : threads) thread.join();

  const double stream_cpu =
      100.0 * static_cast<double>(ticks_after - ticks_before) / static_cast<double>(::sysconf(_SC_CLK_TCK)) / window;
  std::vector<double> fps, latency;
  int failed = 0;
  for (auto& viewer : viewers) {
    failed += viewer->failed ? 1 : 0;
    fps.push_back(static_cast<double>(viewer->frames_at_end - viewer->frames_at_start) / window);
    latency.insert(latency.end(), viewer->latency_ms.begin(), viewer->latency_ms.end());
  }
  const double captured =
      (status_after["frames_captured"].get<double>() - status_before["frames_captured"].get<double>()) / window;
  const double encoded = (status_after["frames_encoded"].get<double>() - status_before["frames_encoded"].get<double>()) / window;

  std::printf("viewers failed:                 %d of %d\n", failed, o.viewers);
  std::printf("viewer fps:                     min %.1f  median %.1f  max %.1f\n", percentile(fps, 0), percentile(fps, 0.5),
              percentile(fps, 1));
  std::printf("rcand CPU (%% of one core):      idle %.1f  streaming %.1f  (streaming - idle: %.1f)\n", idle_cpu, stream_cpu,
              stream_cpu - idle_cpu);
  const double passed =
      (status_after.value("frames_passed_through", 0.0) - status_before.value("frames_passed_through", 0.0)) / window;
  if (host != 0) {
    const double both_cpu =
        100.0 * static_cast<double>(both_after - both_before) / static_cast<double>(::sysconf(_SC_CLK_TCK)) / window;
    std::printf("host %d CPU (%% of one core):   idle %.1f  streaming %.1f;  rcand + host streaming %.1f\n", host, idle_host_cpu,
                both_cpu - stream_cpu, both_cpu);
    std::printf("resident memory streaming:      rcand %.1f MB, host %.1f MB\n", rss_kb / 1024.0, host_rss_kb / 1024.0);
  } else {
    std::printf("resident memory streaming:      rcand %.1f MB\n", rss_kb / 1024.0);
  }
  std::printf("captured / encoded / passed through per second:  %.1f / %.1f / %.1f\n", captured, encoded, passed);
  std::printf("rcand CPU per captured frame:   %.2f ms (streaming)\n", captured > 0 ? stream_cpu * 10.0 / captured : 0.0);
  std::printf("capture -> client (ms):         p50 %.2f  p99 %.2f  max %.2f  (n=%zu)\n", percentile(latency, 0.5),
              percentile(latency, 0.99), percentile(latency, 1), latency.size());
  for (const auto& [what, ms] : {std::pair{"nobody watching", &idle_stops}, std::pair{"while streaming", &streaming_stops}})
    std::printf("POST /api/stop, %-16s p50 %.3f  p99 %.3f  max %.3f ms  (n=%zu)\n", what, percentile(*ms, 0.5),
                percentile(*ms, 0.99), percentile(*ms, 1), ms->size());
  return failed == 0 ? 0 : 1;
} catch (const std::exception& e) {
  std::fprintf(stderr, "bench_vision: %s\n", e.what());
  return 2;
}
