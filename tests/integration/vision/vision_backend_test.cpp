// Which libraries a real rcand maps for its camera (issue 32): on the synthetic camera, neither OpenCV's videoio
// (FFmpeg, GStreamer) nor its imgcodecs (GDAL, TIFF, WebP...), even while it streams; a device, file or URL camera loads
// the video backend module from beside the vision plugin (here the build tree's plugin directory); a plugin directory
// without the module makes such a camera a named fault, never a silent test pattern.
#include <doctest/doctest.h>

#include <cstdlib>
#include <fstream>
#include <sstream>

#include "eventually.hpp"
#include "mjpeg_client.hpp"
#include "rcand_process.hpp"
#include "temp_dir.hpp"

using namespace rcand::test;
using namespace std::chrono_literals;
using nlohmann::json;
namespace fs = std::filesystem;

namespace {

json backend_test_config(json camera) {
  auto config = sim_config();
  config["camera"] = std::move(camera);
  config["rcan_protocol"]["capabilities"] = {"status", "teleop", "vision"};
  return config;
}

// A process's mapped files (/proc/PID/maps), one string.
std::string mapped_files(int pid) {
  std::ifstream maps("/proc/" + std::to_string(pid) + "/maps");
  std::ostringstream text;
  text << maps.rdbuf();
  return text.str();
}

json backend_vision_status(const RcandProcess& rcand) {
  return rcand.json("GET", "/api/status", "guest-token")["capabilities"]["vision"];
}

// The process vision runs in: rcand, or with isolation: process (RCAND_TEST_ISOLATE=vision) its host, whose pid its
// status names.
int vision_pid(const RcandProcess& rcand) {
  const json process = backend_vision_status(rcand)["status"]["process"];
  return process.is_object() ? process["pid"].get<int>() : static_cast<int>(rcand.pid());
}

std::string mapped_files(const RcandProcess& rcand) { return mapped_files(vision_pid(rcand)); }

}  // namespace

TEST_CASE("vision: a robot on the synthetic camera maps no video backend and no image codec library, even streaming") {
  RcandProcess rcand(backend_test_config({{"type", "synthetic"}, {"resolution", {160, 120}}, {"fps", 30}}));
  MjpegClient viewer(rcand.port());
  REQUIRE(viewer.open("/api/stream/mjpeg?token=guest-token") == 200);
  for (int i = 0; i < 3; ++i) REQUIRE(viewer.next_part());  // frames encoded and sent
  const std::string maps = mapped_files(rcand);
  REQUIRE(maps.find("rcand_vision.so") != std::string::npos);
  for (const char* library : {"libopencv_videoio", "libopencv_imgcodecs", "rcand_vision_videoio", "libavcodec", "libgst"})
    CHECK_MESSAGE(maps.find(library) == std::string::npos, library);
  if (std::getenv("RCAND_TEST_ISOLATE") != nullptr) {  // isolated: rcand itself maps neither vision nor OpenCV
    REQUIRE(vision_pid(rcand) != static_cast<int>(rcand.pid()));
    const std::string own = mapped_files(static_cast<int>(rcand.pid()));
    for (const char* library : {"rcand_vision.so", "libopencv"}) CHECK_MESSAGE(own.find(library) == std::string::npos, library);
    // Its manifest says it needs cameras (and the network): its process may open video devices, and no other class.
    const json sandbox = backend_vision_status(rcand)["status"]["process"]["sandbox"];
    INFO(sandbox.dump());
    CHECK((sandbox.value("devices", "") != "restricted" || sandbox["device_classes"] == json{"video"}));
  }
}

TEST_CASE("vision: a device camera loads the video backend module from beside the plugin, on demand") {
  RcandProcess rcand(backend_test_config({{"device", "/dev/video96"}}));
  // The module's words (a stall may be reported first, while the module loads).
  REQUIRE(eventually([&] { return backend_vision_status(rcand)["reason"] == "camera device /dev/video96 does not exist"; }, 10s));
  CHECK(backend_vision_status(rcand)["state"] == "error");
  const std::string maps = mapped_files(rcand);
  CHECK(maps.find((plugin_dir() / "rcand_vision_videoio.so").string()) != std::string::npos);
  CHECK(maps.find("libopencv_videoio") != std::string::npos);
}

TEST_CASE("vision: without the video backend module a file camera is a named fault naming the module") {
  // A plugin directory like the build tree's, without the module (links: dladdr names the directory rcand loaded from).
  TempDir plugins("rcand-no-videoio");
  for (const auto& entry : fs::directory_iterator(plugin_dir()))
    if (entry.is_regular_file() && entry.path().filename() != "rcand_vision_videoio.so")
      fs::create_symlink(entry.path(), plugins.path() / entry.path().filename());
  TempDir media("rcand-media");
  std::ofstream(media.path() / "demo.avi") << "not looked at: the module is missing before the file is opened";
  RcandProcess rcand(backend_test_config({{"type", "file"}, {"path", (media.path() / "demo.avi").string()}}), {plugins.path()});
  const std::string fault = "the video backend module rcand_vision_videoio.so is not installed: " +
                            (plugins.path() / "rcand_vision_videoio.so").string() +
                            " does not exist (it comes with the vision plugin, package rcand-plugins-vision)";
  REQUIRE(eventually([&] { return backend_vision_status(rcand)["reason"] == fault; }, 10s));
  CHECK(backend_vision_status(rcand)["state"] == "error");
  CHECK(mapped_files(rcand).find("libopencv_videoio") == std::string::npos);
}
