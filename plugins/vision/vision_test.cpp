// vision on the fake host, with the SDK's RecordingStream as the viewers: encode-once with 1 and 20 viewers, a
// stalled viewer that holds one frame and slows nobody, ?fps=, the viewer limit, camera loss and recovery (a scripted
// source, a source that hangs, a video file that disappears), a generated AVI played in a loop, bad input (bad fps, a
// missing device, a file that is not video, config errors naming the key) and snapshots. No camera, no sleeps: every
// wait is on an event, bounded.
#include <doctest/doctest.h>

#include <rcand/sdk/testing/fake_host.hpp>
#include <rcand/sdk/testing/recording_stream.hpp>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <deque>
#include <filesystem>
#include <fstream>
#include <thread>

#include "eventually.hpp"
#include "temp_dir.hpp"
#include "vision.hpp"

using namespace std::chrono_literals;
using nlohmann::json;
using rcand::plugins::vision::Encoder;
using rcand::plugins::vision::FrameHub;
using rcand::plugins::vision::FrameSource;
using rcand::plugins::vision::jpeg_encoder;
using rcand::plugins::vision::SourceError;
using rcand::plugins::vision::SourceFactory;
using rcand::plugins::vision::Vision;
using rcand::sdk::Request;
using rcand::sdk::StreamPart;
using rcand::sdk::testing::FakeHost;
using rcand::sdk::testing::HostError;
using rcand::sdk::testing::RecordingStream;

namespace {

// What the next Vision the fake host makes is built with (empty: the real encoder, the config's source).
struct TestHooks {
  Encoder encoder;
  SourceFactory sources;
} g_hooks;

void register_vision_for_test(rcand::sdk::Registrar& registrar) {
  registrar.add_capability({"vision", false}, [](rcand::sdk::PluginContext& ctx) {
    return std::make_unique<Vision>(ctx, g_hooks.encoder, g_hooks.sources);
  });
}

}  // namespace

RCAND_PLUGIN("org.rcand.vision", "0.1.0", register_vision_for_test)

namespace {

json manifest() {
  std::ifstream in(RCAND_SOURCE_DIR "/manifests/vision.json");
  REQUIRE(in.good());
  return json::parse(in);
}

// A camera the test drives frame by frame: read() waits for a frame the test queued, a failure, or the end.
struct Script {
  std::mutex mutex;
  std::condition_variable changed;
  std::deque<cv::Mat> frames;
  bool fail = false, released = false;
  int open_failures = 0, opens = 0;
  double fps = 30;  // what the source reports; set before the rig starts

  void push(int shade) {
    std::lock_guard lock(mutex);
    frames.emplace_back(48, 64, CV_8UC3, cv::Scalar(shade, shade, shade));
    changed.notify_all();
  }
  void fail_now(int then_open_failures) {
    std::lock_guard lock(mutex);
    fail = true;
    open_failures = then_open_failures;
    changed.notify_all();
  }
  void release() {
    std::lock_guard lock(mutex);
    released = true;
    changed.notify_all();
  }
};

class ScriptedSource final : public FrameSource {
 public:
  explicit ScriptedSource(std::shared_ptr<Script> script) : script_(std::move(script)) {}
  void open() override {
    std::lock_guard lock(script_->mutex);
    ++script_->opens;
    if (script_->open_failures > 0) {
      --script_->open_failures;
      throw SourceError("scripted camera is unplugged");
    }
  }
  bool read(cv::Mat& frame) override {
    std::unique_lock lock(script_->mutex);
    script_->changed.wait(lock, [&] { return !script_->frames.empty() || script_->fail || script_->released; });
    if (script_->released) return false;
    if (script_->fail) {
      script_->fail = false;
      return false;
    }
    frame = std::move(script_->frames.front());
    script_->frames.pop_front();
    return true;
  }
  bool paced() const noexcept override { return false; }
  double fps() const noexcept override { return script_->fps; }
  std::string describe() const override { return "scripted camera"; }

 private:
  std::shared_ptr<Script> script_;
};

// Releases the script before the host shuts the plugin down (declared after the host: destroyed first), so no
// capture thread is left waiting in read().
struct ReleaseOnExit {
  std::shared_ptr<Script> script;
  ~ReleaseOnExit() { script->release(); }
};

struct CountingEncoder {
  std::shared_ptr<std::atomic<int>> calls = std::make_shared<std::atomic<int>>(0);
  Encoder encoder() const {
    return [calls = calls, real = jpeg_encoder(80)](const cv::Mat& image) {
      ++*calls;
      return real(image);
    };
  }
};

// A vision instance on a fake host; `camera` is the robot's camera block, `settings` runtime.capabilities.vision.
struct Rig {
  FakeHost host;
  Vision* vision = nullptr;

  explicit Rig(json camera, json settings = json::object(), TestHooks hooks = {}) : host(json{{"camera", std::move(camera)}}) {
    g_hooks = std::move(hooks);
    host.load(RCAND_ENTRY_FUNCTION, manifest());
    host.add_capability("vision", std::move(settings));
    vision = &host.capability<Vision>("vision");
    g_hooks = {};
  }
  FrameHub& hub() { return vision->hub(); }

  // A request through the stream route at `path`, answered into a new RecordingStream.
  std::shared_ptr<RecordingStream> get(const std::string& path, std::map<std::string, std::string> query = {},
                                       RecordingStream::Client client = RecordingStream::Client::Reads,
                                       rcand::sdk::Role role = rcand::sdk::Role::Owner) {
    auto writer = std::make_shared<RecordingStream>(client);
    Request request;
    request.method = "GET";
    request.path = path;
    request.query = std::move(query);
    request.principal = "tester";
    request.role = role;
    for (auto& route : vision->stream_routes())
      if (route.path == path) route.handler(request, writer);
    return writer;
  }
  json camera_status() { return vision->status()["camera"]; }
  // Waits until the hub made `rounds` deliveries in all.
  bool delivered(std::uint64_t rounds) {
    return hub().wait([&](const FrameHub::Counts& c) { return c.rounds >= rounds; }, 2s);
  }
};

std::string header(const StreamPart& part, const std::string& name) {
  for (const auto& [key, value] : part.headers)
    if (key == name) return value;
  return {};
}

bool signal_none(const std::vector<StreamPart>& parts) { return !parts.empty() && header(parts.back(), "X-Signal") == "none"; }
bool signal_live(const std::vector<StreamPart>& parts) { return !parts.empty() && header(parts.back(), "X-Signal") == "live"; }

cv::Mat decode(const StreamPart& part) {
  REQUIRE(part.data);
  const std::vector<uchar> bytes(part.data->begin(), part.data->end());
  return cv::imdecode(bytes, cv::IMREAD_COLOR);
}

// A 160x120 MJPG AVI of `frames` frames at 30 fps (the video file a test plays).
void write_avi(const std::filesystem::path& file, int frames) {
  // OpenCV's own MJPEG writer: no FFmpeg or GStreamer in the test's way.
  cv::VideoWriter writer(file.string(), cv::CAP_OPENCV_MJPEG, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 30,
                         cv::Size(160, 120));
  REQUIRE(writer.isOpened());
  for (int i = 0; i < frames; ++i) {
    cv::Mat frame(120, 160, CV_8UC3, cv::Scalar(i * 20 % 255, 100, 200));
    cv::putText(frame, std::to_string(i), cv::Point(10, 60), cv::FONT_HERSHEY_SIMPLEX, 1.0, cv::Scalar(255, 255, 255), 2);
    writer.write(frame);
  }
}

json scripted_camera() { return {{"type", "synthetic"}}; }  // replaced by the scripted source

// For what only time brings (a reading going stale, the depth thread's first frame, a camera's fault).
using rcand::test::eventually;

}  // namespace

TEST_CASE("vision: each frame is encoded once, for 1 viewer and for 20, and not at all with none") {
  auto script = std::make_shared<Script>();
  CountingEncoder counting;
  Rig rig(scripted_camera(), {}, {counting.encoder(), [script] { return std::make_unique<ScriptedSource>(script); }});
  ReleaseOnExit release{script};

  for (int i = 0; i < 5; ++i) script->push(10 * i);
  REQUIRE(rig.hub().wait([](const FrameHub::Counts& c) { return c.captured >= 5; }, 2s));
  CHECK(*counting.calls == 0);  // nobody watches: nothing is encoded

  auto first = rig.get("/api/stream/mjpeg");
  REQUIRE(first->status() == 200);
  CHECK(first->content_type() == "multipart/x-mixed-replace");
  // A new viewer may first get the newest frame captured before it came (whether the delivery thread had already
  // passed it is timing); a sync frame pins where the counted frames start.
  script->push(99);
  REQUIRE(first->wait_until([](const auto& parts) { return !parts.empty() && header(parts.back(), "X-Frame") == "6"; }, 2s));
  const auto calls = [&] { return static_cast<std::size_t>(counting.calls->load()); };
  const std::size_t calls_before = calls();
  const std::size_t parts_before = first->parts().size();
  CHECK(calls_before == parts_before);    // one encode per part so far
  for (std::size_t i = 0; i < 10; ++i) {  // each frame waited for, so none replaces another
    script->push(static_cast<int>(i));
    REQUIRE(first->wait_for_parts(parts_before + i + 1, 2s));
  }
  CHECK(calls() - calls_before == 10);
  CHECK(first->parts().size() - parts_before == 10);

  std::vector<std::shared_ptr<RecordingStream>> more;
  for (int i = 0; i < 19; ++i) more.push_back(rig.get("/api/stream/mjpeg"));
  for (std::size_t i = 0; i < 10; ++i) {
    script->push(100 + static_cast<int>(i));
    REQUIRE(first->wait_for_parts(parts_before + 11 + i, 2s));
    for (const auto& viewer : more) REQUIRE(viewer->wait_for_parts(i + 1, 2s));
  }
  CHECK(calls() - calls_before == 20);  // 20 viewers: still one encode per frame
  CHECK(rig.hub().counts().encoded == calls());
  const auto reference = first->parts();
  REQUIRE(reference.size() == parts_before + 20);
  for (const auto& viewer : more) {
    const auto parts = viewer->parts();
    REQUIRE(parts.size() == 10);
    for (std::size_t i = 0; i < parts.size(); ++i)
      CHECK(parts[i].data.get() == reference[parts_before + 10 + i].data.get());  // the same bytes, shared, not copied
  }
  CHECK(decode(reference.back()).cols == 64);
  CHECK(rig.vision->status()["viewers"].size() == 20);
}

TEST_CASE("vision: a viewer that never reads holds at most one frame and does not slow another") {
  auto script = std::make_shared<Script>();
  Rig rig(scripted_camera(), {}, {{}, [script] { return std::make_unique<ScriptedSource>(script); }});
  ReleaseOnExit release{script};
  auto stalled = rig.get("/api/stream/mjpeg", {}, RecordingStream::Client::Stalled);
  auto reader = rig.get("/api/stream/mjpeg");
  for (int i = 0; i < 30; ++i) {
    script->push(i);
    REQUIRE(rig.delivered(static_cast<std::uint64_t>(i + 1)));
    CHECK(reader->parts().size() == static_cast<std::size_t>(i + 1));  // every frame, as it comes
  }
  CHECK(stalled->parts().empty());
  CHECK(stalled->has_pending());             // exactly one frame waits for it...
  CHECK(stalled->counters().dropped == 29);  // ...the 29 before it were replaced, never queued
  stalled->take();
  REQUIRE(stalled->parts().size() == 1);
  CHECK(header(stalled->parts()[0], "X-Frame") == "30");  // and what it gets is the newest
  const auto viewers = rig.vision->status()["viewers"];
  REQUIRE(viewers.size() == 2);
}

TEST_CASE("vision: ?fps= gives a viewer fewer frames; a bad one is 400 naming the field") {
  Rig rig({{"type", "synthetic"}, {"resolution", {160, 120}}, {"fps", 30}});
  auto full = rig.get("/api/stream/mjpeg");
  auto third = rig.get("/api/stream/mjpeg", {{"fps", "10"}});
  REQUIRE(full->wait_for_parts(31, 5s));  // about a second of the 30 fps source
  const auto got = third->parts().size();
  CHECK(got >= 8);
  CHECK(got <= 13);
  CHECK(full->parts().size() > 2 * got);

  for (const std::string bad : {"abc", "0", "-1", "121", "nan", "inf", "15fps", "", "1e400", "0.001", "0.19"}) {
    CAPTURE(bad);
    auto refused = rig.get("/api/stream/mjpeg", {{"fps", bad}});
    CHECK(refused->status() == 400);
    CHECK(refused->json()["field"] == "fps");
    CHECK(refused->json()["code"] == "BAD_REQUEST");
  }
  CHECK(rig.get("/api/stream/mjpeg", {{"fps", "7.5"}})->status() == 200);
}

TEST_CASE("vision: the viewer limit answers 503 naming it, and frees a place when a viewer leaves") {
  Rig rig({{"type", "synthetic"}, {"resolution", {160, 120}}}, {{"max_viewers", 2}});
  auto a = rig.get("/api/stream/mjpeg");
  auto b = rig.get("/api/stream/mjpeg");
  auto c = rig.get("/api/stream/mjpeg");
  CHECK(a->status() == 200);
  CHECK(b->status() == 200);
  REQUIRE(c->status() == 503);
  CHECK(c->json()["limit"] == 2);
  CHECK(c->json()["code"] == "UNAVAILABLE");
  CHECK(c->json()["error"].get<std::string>().find("max_viewers") != std::string::npos);
  CHECK(c->headers() == rcand::sdk::Headers{{"Retry-After", "5"}});
  a->close_client();
  CHECK(rig.get("/api/stream/mjpeg")->status() == 200);
}

TEST_CASE("vision: the last reserved_viewers places are the operators'; a guest always has one when nobody watches") {
  using rcand::sdk::Role;
  const auto reads = RecordingStream::Client::Reads;
  SUBCASE("the last places are the OWNER's and CREATOR's") {
    Rig rig({{"type", "synthetic"}, {"resolution", {160, 120}}}, {{"max_viewers", 4}, {"reserved_viewers", 2}});
    auto guest = rig.get("/api/stream/mjpeg", {}, reads, Role::Guest);
    auto user = rig.get("/api/stream/mjpeg", {}, reads, Role::User);
    auto late = rig.get("/api/stream/mjpeg", {}, reads, Role::Leasee);
    CHECK(guest->status() == 200);
    CHECK(user->status() == 200);
    REQUIRE(late->status() == 503);  // was 200: and the owner's dashboard then met the viewer limit
    CHECK(late->json()["code"] == "SLOTS_RESERVED");
    CHECK(late->json()["field"] == "reserved_viewers");
    CHECK(late->headers() == rcand::sdk::Headers{{"Retry-After", "5"}});
    auto owner = rig.get("/api/stream/mjpeg", {}, reads, Role::Owner);
    auto creator = rig.get("/api/stream/mjpeg", {}, reads, Role::Creator);
    CHECK(owner->status() == 200);
    CHECK(creator->status() == 200);
    CHECK(rig.get("/api/stream/mjpeg", {}, reads, Role::Owner)->json()["code"] == "UNAVAILABLE");
  }
  SUBCASE("more reserved than places: a guest still has one") {
    Rig tiny({{"type", "synthetic"}, {"resolution", {160, 120}}}, {{"max_viewers", 2}, {"reserved_viewers", 8}});
    auto first = tiny.get("/api/stream/mjpeg", {}, reads, Role::Guest);
    CHECK(first->status() == 200);
    CHECK(tiny.get("/api/stream/mjpeg", {}, reads, Role::Guest)->status() == 503);
  }
}

TEST_CASE("vision: a camera that fails turns into NO SIGNAL within 1 s and comes back by itself") {
  auto script = std::make_shared<Script>();
  Rig rig(scripted_camera(), {{"reconnect_max_ms", 100}}, {{}, [script] { return std::make_unique<ScriptedSource>(script); }});
  ReleaseOnExit release{script};
  auto viewer = rig.get("/api/stream/mjpeg");
  script->push(50);
  REQUIRE(viewer->wait_until(signal_live, 2s));
  CHECK(rig.camera_status()["state"] == "live");

  const auto failed_at = std::chrono::steady_clock::now();
  script->fail_now(2);  // read() fails, then two opens fail
  REQUIRE(viewer->wait_until(signal_none, 1s));
  CHECK(std::chrono::steady_clock::now() - failed_at < 1s);
  const auto lost = decode(viewer->parts().back());
  CHECK(lost.cols == 64);  // NO SIGNAL at the camera's own size, so the page layout holds
  const auto status = rig.camera_status();
  CHECK(status["state"] == "no_signal");
  CHECK(status["fault"].get<std::string>().find("scripted camera") != std::string::npos);
  CHECK(rig.host.last_published_status("vision").has_value());

  script->push(60);  // read once the third open succeeds
  REQUIRE(viewer->wait_until(signal_live, 3s));
  CHECK(rig.camera_status()["state"] == "live");
  CHECK(rig.camera_status()["fault"].is_null());
  CHECK(rig.camera_status()["reconnects"] == 1);
  std::lock_guard lock(script->mutex);
  CHECK(script->opens == 4);
}

TEST_CASE("vision: a source whose read() hangs is NO SIGNAL within 1 s of its last frame") {
  auto script = std::make_shared<Script>();
  Rig rig(scripted_camera(), {{"signal_timeout_ms", 500}}, {{}, [script] { return std::make_unique<ScriptedSource>(script); }});
  ReleaseOnExit release{script};
  auto viewer = rig.get("/api/stream/mjpeg");
  script->push(1);
  REQUIRE(viewer->wait_until(signal_live, 2s));
  const auto last_frame = std::chrono::steady_clock::now();
  REQUIRE(viewer->wait_until(signal_none, 2s));  // read() never returns
  CHECK(std::chrono::steady_clock::now() - last_frame < 1s);
  CHECK(rig.camera_status()["fault"].get<std::string>().find("no frame from scripted camera") != std::string::npos);
}

TEST_CASE("vision: a stall is two frame periods without a frame, at least 250 ms; the status's top-level fault says so") {
  for (const auto& fps_threshold_case :
       std::vector<std::pair<double, std::string>>{{30, "250 ms"}, {4, "500 ms"}, {1e-300, "60000 ms"}}) {
    const auto& fps = fps_threshold_case.first;  // clang 14: CAPTURE's lambda cannot capture a structured binding
    const auto& threshold = fps_threshold_case.second;
    CAPTURE(fps);
    auto script = std::make_shared<Script>();
    script->fps = fps;
    Rig rig(scripted_camera(), {}, {{}, [script] { return std::make_unique<ScriptedSource>(script); }});
    ReleaseOnExit release{script};
    auto viewer = rig.get("/api/stream/mjpeg");
    script->push(1);
    REQUIRE(viewer->wait_until(signal_live, 2s));
    CHECK(rig.vision->status()["fault"].is_null());  // live: nothing for the kernel to report
    if (fps < 1) continue;                           // a minute: not waited for here
    REQUIRE(viewer->wait_until(signal_none, 3s));    // read() never returns
    const std::string fault = "no frame from scripted camera for " + threshold;
    CHECK(rig.camera_status()["fault"] == fault);
    CHECK(rig.vision->status()["fault"] == fault);  // the SDK's convention: the kernel shows the capability as error
    REQUIRE(eventually([&] { return rig.host.last_published_status("vision").value_or(json())["fault"] == fault; }, 2s));
    script->push(2);
    REQUIRE(viewer->wait_until(signal_live, 2s));
    CHECK(rig.vision->status()["fault"].is_null());
    REQUIRE(eventually([&] { return rig.host.last_published_status("vision").value_or(json())["fault"].is_null(); }, 2s));
  }
}

TEST_CASE("vision: a generated video file plays in a loop, and its disappearance is NO SIGNAL until it returns") {
  rcand::test::TempDir dir;
  const auto file = dir.path() / "clip.avi";
  write_avi(file, 12);
  Rig rig({{"type", "file"}, {"path", file.string()}}, {{"reconnect_max_ms", 100}});
  auto viewer = rig.get("/api/stream/mjpeg");
  REQUIRE(viewer->wait_for_parts(30, 5s));  // 12 frames at 30 fps: looped twice by now
  CHECK(rig.hub().counts().captured >= 30);
  const auto parts = viewer->parts();
  for (const auto& part : parts) {
    const auto image = decode(part);
    CHECK(image.cols == 160);
    CHECK(image.rows == 120);
    CHECK(header(part, "X-Signal") == "live");
  }
  CHECK(rig.camera_status()["source"] == "file " + file.string());

  const auto removed_at = std::chrono::steady_clock::now();
  std::filesystem::remove(file);
  REQUIRE(viewer->wait_until(signal_none, 1s));
  CHECK(std::chrono::steady_clock::now() - removed_at < 1s);
  CHECK(rig.camera_status()["fault"].get<std::string>().find(file.string() + " does not exist") != std::string::npos);

  write_avi(file, 12);
  REQUIRE(viewer->wait_until(signal_live, 3s));
  CHECK(rig.camera_status()["state"] == "live");
}

TEST_CASE("vision: bad sources are named faults, never a silent test pattern") {
  rcand::test::TempDir dir;
  SUBCASE("a file that is not video") {
    const auto file = dir.write("notes.avi", "these are not frames\n");
    Rig rig({{"type", "file"}, {"path", file.string()}});
    auto viewer = rig.get("/api/stream/mjpeg");
    REQUIRE(viewer->wait_until(signal_none, 2s));
    CHECK(rig.camera_status()["fault"] == "video file " + file.string() + " is not a video OpenCV can read");
    CHECK(rig.camera_status()["source"] == "file " + file.string());
  }
  SUBCASE("a V4L2 device that does not exist") {
    Rig rig({{"type", "usb"}, {"device", "/dev/video97"}});
    auto viewer = rig.get("/api/stream/mjpeg");
    REQUIRE(viewer->wait_until(signal_none, 2s));
    CHECK(rig.camera_status()["fault"] == "camera device /dev/video97 does not exist");
  }
  SUBCASE("a camera block without a type is a V4L2 device, never the synthetic source") {
    Rig rig({{"device", 96}});
    CHECK(rig.vision->settings().source.location == "/dev/video96");
    auto viewer = rig.get("/api/stream/mjpeg");
    REQUIRE(viewer->wait_until(signal_none, 2s));
    CHECK(rig.camera_status()["fault"] == "camera device /dev/video96 does not exist");
  }
  SUBCASE("a URL that never answers") {
    Rig rig({{"type", "rtsp"}, {"url", "rtsp://user:secret@127.0.0.1:9/none"}}, {{"open_timeout_ms", 300}});
    auto viewer = rig.get("/api/stream/mjpeg");
    REQUIRE(viewer->wait_until(signal_none, 3s));
    const std::string fault = rig.camera_status()["fault"];
    CHECK(fault.find("rtsp://***@127.0.0.1:9/none") != std::string::npos);
    CHECK(fault.find("secret") == std::string::npos);
  }
}

namespace {

// A camera that hangs: a TCP server on 127.0.0.1 whose connections complete (the kernel accepts them into the
// backlog) and never see a byte, neither an HTTP status line nor an RTSP reply.
struct SilentServer {
  int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  int port = 0;
  SilentServer() {
    REQUIRE(fd >= 0);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    REQUIRE(::bind(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) == 0);
    REQUIRE(::listen(fd, 16) == 0);
    socklen_t length = sizeof address;
    REQUIRE(::getsockname(fd, reinterpret_cast<sockaddr*>(&address), &length) == 0);
    port = ntohs(address.sin_port);
  }
  ~SilentServer() { ::close(fd); }
};

}  // namespace

TEST_CASE("vision: a URL camera that accepts and never answers hangs neither startup nor the stop path") {
  using Clock = std::chrono::steady_clock;
  for (const std::string scheme : {"http", "rtsp"}) {
    // 500 ms: open() gives up and names the fault. 20 s: the capture thread is still inside open() at shutdown.
    for (const int open_timeout_ms : {500, 20'000}) {
      CAPTURE(scheme);
      CAPTURE(open_timeout_ms);
      SilentServer camera;
      const std::string url = scheme + "://127.0.0.1:" + std::to_string(camera.port) + "/stream";
      Clock::time_point stopping;
      {
        const auto starting = Clock::now();
        Rig rig({{"type", scheme}, {"url", url}}, {{"open_timeout_ms", open_timeout_ms}, {"read_timeout_ms", 500}});
        CHECK(Clock::now() - starting < 500ms);  // start() hands the camera to its thread and returns
        {
          auto viewer = rig.get("/api/stream/mjpeg");
          REQUIRE(viewer->wait_until(signal_none, 3s));  // a live stream of NO SIGNAL frames meanwhile
          CHECK(rig.camera_status()["state"] == "no_signal");
          if (open_timeout_ms == 500) {
            // A stall (no frame for 250 ms) is reported first; the failed open replaces it at 500 ms.
            REQUIRE(eventually(
                [&] {
                  const json fault = rig.camera_status()["fault"];
                  return fault.is_string() && fault.get<std::string>().starts_with("camera URL");
                },
                2s));
            CHECK(rig.camera_status()["fault"] == "camera URL " + url + " did not open within 500 ms, or is not a video stream");
          }
        }
        stopping = Clock::now();  // the rig shuts down next, with its capture thread in open() or between two tries
      }
      CHECK(Clock::now() - stopping < 2s);  // at most the capture thread's grace (1.5 s), then it is left behind
    }
  }
}

TEST_CASE("vision: config errors name the key") {
  auto error_of = [](json camera) {
    try {
      Rig rig(std::move(camera));
    } catch (const HostError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  CHECK(error_of({{"type", "laser"}}).find("camera.type: unknown camera type 'laser'") != std::string::npos);
  CHECK(error_of({{"type", "synthetic"}, {"resolution", {640}}}).find("camera.resolution") != std::string::npos);
  CHECK(error_of({{"type", "synthetic"}, {"fps", -1}}).find("camera.fps") != std::string::npos);
  CHECK(error_of({{"type", "usb"}, {"fourcc", "MJPEG"}}).find("camera.fourcc") != std::string::npos);
  CHECK(error_of({{"type", "file"}}).find("camera.path") != std::string::npos);
  CHECK(error_of({{"type", "url"}}).find("camera.url") != std::string::npos);
  CHECK(error_of({{"type", "snapshot"}}).find("camera.url: a snapshot camera needs the URL of its picture") != std::string::npos);
  CHECK(error_of({{"type", "snapshot"}, {"url", "https://u:pw@cam/snap.jpg"}})
            .find("camera.url: https://***@cam/snap.jpg: https is not supported") != std::string::npos);
  CHECK(error_of({{"type", "synthetic"}, {"width", "wide"}}).find("width") != std::string::npos);
}

TEST_CASE("vision: a snapshot is one JPEG, encoded once, also while nobody streams") {
  CountingEncoder counting;
  Rig rig({{"type", "synthetic"}, {"resolution", {320, 240}}}, {}, {counting.encoder(), {}});
  auto snapshot = rig.get("/api/stream/snapshot");
  REQUIRE(snapshot->wait_for_answer(2s));
  CHECK(snapshot->status() == 200);
  CHECK(snapshot->content_type() == "image/jpeg");
  const std::string body = snapshot->body();
  const auto image = cv::imdecode(std::vector<uchar>(body.begin(), body.end()), cv::IMREAD_COLOR);
  CHECK(image.cols == 320);
  CHECK(image.rows == 240);
  CHECK(*counting.calls == 1);
}

TEST_CASE("vision: ?fps= parsing") {
  std::string error;
  CHECK(rcand::plugins::vision::parse_fps("15", error) == 15.0);
  CHECK(rcand::plugins::vision::parse_fps("0.5", error) == 0.5);
  CHECK(rcand::plugins::vision::parse_fps("120", error) == 120.0);
  CHECK_FALSE(rcand::plugins::vision::parse_fps(" 15", error));
  CHECK_FALSE(rcand::plugins::vision::parse_fps("0x10", error));
  CHECK(rcand::plugins::vision::parse_fps("0.2", error) == 0.2);
  CHECK_FALSE(rcand::plugins::vision::parse_fps("0.001", error));  // a frame every 1000 s: would only hold a place
  CHECK(error == "fps must be a number in [0.2, 120]: a stream offered no frame for 10 s is closed");
}

// ---- depth ------------------------------------------------------------------------------------------------------

namespace {

using rcand::plugins::vision::compute_zones;
using rcand::plugins::vision::DepthFeed;
using rcand::plugins::vision::DepthSettings;
using rcand::plugins::vision::ZoneOptions;

cv::Mat wall(std::uint16_t mm) { return cv::Mat(400, 640, CV_16UC1, cv::Scalar(mm)); }

}  // namespace

TEST_CASE("depth zones: one noisy pixel does not stop the robot, a 5 cm object at 30 cm does") {
  const ZoneOptions options;
  auto depth = wall(3000);
  depth.at<std::uint16_t>(200, 320) = 300;  // one spike in the centre
  auto zones = compute_zones(depth, options, 1);
  REQUIRE(zones.available);
  CHECK(zones.center_cm == 300);
  CHECK(zones.nearest_cm == 300);
  // 5 cm at 30 cm is about 76 pixels across on a 640-pixel, 70-degree camera.
  depth(cv::Rect(282, 160, 76, 76)).setTo(cv::Scalar(300));
  zones = compute_zones(depth, options, 2);
  CHECK(zones.center_cm == 30);
  CHECK(zones.left_cm == 300);
  CHECK(zones.right_cm == 300);
  CHECK(zones.nearest_cm == 30);
  CHECK(zones.timestamp_ms == 2);
}

TEST_CASE("depth zones fail safe: no reading and too near count as blocked; beyond the range is free; the floor band") {
  const ZoneOptions options;  // 200 mm .. 4000 mm
  SUBCASE("pixels with no reading are blocked at the near range, not free") {
    auto depth = wall(3000);
    depth(cv::Rect(40, 180, 40, 40)).setTo(cv::Scalar(0));
    CHECK(compute_zones(depth, options, 0).left_cm == 20);
    auto one = wall(3000);
    one.at<std::uint16_t>(10, 10) = 0;  // a single dropout is noise
    CHECK(compute_zones(one, options, 0).left_cm == 300);
  }
  SUBCASE("nearer than the sensor's minimum range is the minimum range") {
    auto depth = wall(3000);
    depth(cv::Rect(500, 180, 40, 40)).setTo(cv::Scalar(100));
    CHECK(compute_zones(depth, options, 0).right_cm == 20);
  }
  SUBCASE("a whole frame with no reading is blocked everywhere") {
    const auto zones = compute_zones(wall(0), options, 0);
    CHECK(zones.available);
    CHECK(zones.nearest_cm == 20);
  }
  SUBCASE("beyond the maximum range is free: the zone reads the maximum") {
    const auto zones = compute_zones(wall(6000), options, 0);
    CHECK(zones.left_cm == 400);
    CHECK(zones.nearest_cm == 400);
  }
  SUBCASE("a row band leaves out the floor") {
    auto depth = wall(3000);
    depth(cv::Rect(0, 330, 640, 70)).setTo(cv::Scalar(400));  // the floor in the bottom rows
    CHECK(compute_zones(depth, options, 0).nearest_cm == 40);
    ZoneOptions banded;
    banded.roi_bottom = 0.8;
    CHECK(compute_zones(depth, banded, 0).nearest_cm == 300);
  }
  SUBCASE("not a depth frame") { CHECK_FALSE(compute_zones(cv::Mat(10, 10, CV_8UC3), options, 0).available); }
}

TEST_CASE("depth: the synthetic scene's objects approach and recede but never come nearer than 1 m; a placed one does") {
  const ZoneOptions options;
  rcand::plugins::vision::SyntheticScene scene;
  const auto far = compute_zones(scene.render(640, 400, 0.0), options, 0);
  const auto near = compute_zones(scene.render(640, 400, 6.0), options, 0);
  const auto back = compute_zones(scene.render(640, 400, 12.0), options, 0);
  CHECK(far.center_cm == 300);
  CHECK(near.center_cm == 100);
  CHECK(back.center_cm == 300);
  CHECK(near.left_cm > 100);
  double nearest = 1e9;
  for (double t = 0; t < 252; t += 0.25)
    nearest = std::min(nearest, compute_zones(scene.render(160, 120, t), options, 0).nearest_cm);
  CHECK(nearest == 100);  // the whole 252 s cycle of the three periods: 1 m at the nearest

  scene.place(2, 0.25);
  auto placed = compute_zones(scene.render(640, 400, 6.0), options, 0);
  CHECK(placed.right_cm == 25);
  CHECK(placed.center_cm == 100);
  CHECK(placed.nearest_cm == 25);
  scene.place(2, std::nullopt);
  CHECK(compute_zones(scene.render(640, 400, 6.0), options, 0).right_cm > 100);
}

TEST_CASE("depth: a reading older than max_age is unavailable, for the route and for the ObstacleSource") {
  DepthSettings settings;
  settings.max_age = 50ms;
  DepthFeed feed(settings);
  CHECK_FALSE(feed.obstacles().available);  // nothing yet: unavailable, never clear
  CHECK(feed.obstacles().timestamp_ms == 0);
  feed.feed(wall(1000), 42);
  const auto fresh = feed.obstacles();
  REQUIRE(fresh.available);
  CHECK(fresh.nearest_cm == 100);
  CHECK(fresh.timestamp_ms == 42);
  const auto fed = std::chrono::steady_clock::now();
  REQUIRE(eventually([&] { return !feed.zones().available; }, 2s));
  CHECK(std::chrono::steady_clock::now() - fed >= 50ms);
  CHECK(feed.zones().reason.rfind("stale", 0) == 0);
  CHECK_FALSE(feed.obstacles().available);
  CHECK(feed.obstacles().timestamp_ms == 42);  // still dated, so a reader can say how stale
  feed.feed(cv::Mat(10, 10, CV_8UC3), 43);     // a frame that gives no zones has no reading to date
  CHECK_FALSE(feed.obstacles().available);
  CHECK(feed.obstacles().timestamp_ms == 0);
}

TEST_CASE("depth: POST /api/depth/sim_obstacle places an object in the synthetic scene at once, and removes it") {
  Rig rig({{"type", "synthetic"}, {"resolution", {160, 120}}, {"depth", "synthetic"}});
  const auto* source = rcand::sdk::find<rcand::sdk::ObstacleSource>(rig.host);
  REQUIRE(source != nullptr);
  REQUIRE(eventually([&] { return source->obstacles().available; }, 2s));
  CHECK(source->obstacles().nearest_cm >= 100);

  auto placed =
      rig.host.call("POST", "/api/depth/sim_obstacle", {{"zone", "center"}, {"distance_m", 0.2}}, rcand::sdk::Role::User);
  REQUIRE(placed.status == 200);
  CHECK(placed.body["placed"] == json{{"left", nullptr}, {"center", 0.2}, {"right", nullptr}});
  CHECK(placed.body["obstacles"]["center_cm"] == 20);
  CHECK(placed.body["fed_us"].is_number_integer());
  CHECK(source->obstacles().center_cm == 20);  // fed before the answer: no waiting for the next frame
  for (int i = 0; i < 5; ++i) {                // and every frame after it shows it too
    rig.vision->depth()->refresh();
    CHECK(source->obstacles().center_cm == 20);
  }

  auto removed = rig.host.call("POST", "/api/depth/sim_obstacle", {{"zone", "center"}, {"distance_m", nullptr}});
  REQUIRE(removed.status == 200);
  CHECK(removed.body["placed"]["center"].is_null());
  CHECK(source->obstacles().nearest_cm >= 100);

  for (const auto& [body, field] :
       std::vector<std::pair<json, std::string>>{{json::array(), "body"},
                                                 {{{"zone", "middle"}, {"distance_m", 1}}, "zone"},
                                                 {{{"distance_m", 1}}, "zone"},
                                                 {{{"zone", "left"}}, "distance_m"},
                                                 {{{"zone", "left"}, {"distance_m", -1}}, "distance_m"},
                                                 {{{"zone", "left"}, {"distance_m", "near"}}, "distance_m"}}) {
    const auto r = rig.host.call("POST", "/api/depth/sim_obstacle", body);
    CHECK(r.status == 400);
    CHECK(r.body["field"] == field);
  }
  CHECK(rig.host.call("POST", "/api/depth/sim_obstacle", {{"zone", "left"}, {"distance_m", 1}}, rcand::sdk::Role::Guest).status ==
        403);
}

TEST_CASE("vision with camera.depth offers the ObstacleSource and serves the zones and the depth frame") {
  Rig rig({{"type", "synthetic"}, {"resolution", {160, 120}}, {"depth", "synthetic"}});
  const auto* source = rcand::sdk::find<rcand::sdk::ObstacleSource>(rig.host);
  REQUIRE(source != nullptr);
  REQUIRE(eventually([&] { return source->obstacles().available; }, 2s));
  const auto answer = rig.host.call("GET", "/api/depth/obstacles", {}, rcand::sdk::Role::Guest);
  REQUIRE(answer.status == 200);
  CHECK(answer.body["available"] == true);
  for (const char* key : {"left_cm", "center_cm", "right_cm", "nearest_cm", "timestamp_ms"}) CHECK(answer.body.contains(key));
  auto frame = rig.get("/api/depth/frame");
  REQUIRE(frame->wait_for_answer(2s));
  CHECK(frame->status() == 200);
  const std::string body = frame->body();
  const auto image = cv::imdecode(std::vector<uchar>(body.begin(), body.end()), cv::IMREAD_COLOR);
  CHECK(image.cols == 640);
  CHECK(image.rows == 400);
}

TEST_CASE("vision without camera.depth: no ObstacleSource, the zones unavailable, no depth frame; bad depth is named") {
  Rig rig({{"type", "synthetic"}, {"resolution", {160, 120}}});
  CHECK(rcand::sdk::find<rcand::sdk::ObstacleSource>(rig.host) == nullptr);
  const auto answer = rig.host.call("GET", "/api/depth/obstacles");
  CHECK(answer.body["available"] == false);
  CHECK(rig.get("/api/depth/frame")->status() == 503);
  CHECK(rig.host.call("POST", "/api/depth/sim_obstacle", {{"zone", "left"}, {"distance_m", 1}}).status == 404);
  try {
    Rig bad({{"type", "usb"}, {"depth", true}});
    FAIL("camera.depth: true was accepted");
  } catch (const HostError& e) {
    CHECK(std::string(e.what()).find("camera.depth") != std::string::npos);
  }
}
