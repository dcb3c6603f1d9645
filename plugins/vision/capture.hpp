// One capture thread per camera: opens the source, reads (pacing synthetic and file sources at their fps), hands each
// frame to the hub, and when the source fails reports it (the hub switches to NO SIGNAL at once) and reopens it with
// a backoff that doubles up to reconnect_max. Faults are named ("camera device /dev/video3 does not exist") and never
// replaced by another source.
#pragma once

#include <chrono>
#include <condition_variable>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "camera_source.hpp"
#include "frame_hub.hpp"

namespace rcand::plugins::vision {

using SourceFactory = std::function<std::unique_ptr<FrameSource>()>;

struct CaptureOptions {
  std::chrono::milliseconds reconnect_min{250}, reconnect_max{5000};
};

class Capture {
 public:
  // `report` gets each new fault, and "recovered" lines, as text (the plugin logs them).
  Capture(SourceFactory factory, CaptureOptions options, std::shared_ptr<FrameHub> hub,
          std::function<void(bool fault, const std::string& text)> report = {});
  ~Capture();
  Capture(const Capture&) = delete;
  Capture& operator=(const Capture&) = delete;

  void start();
  // Asks the thread to stop and waits up to `grace` for it; a thread stuck inside a driver's read() is left to finish
  // on its own (it holds what it uses, the hub included). Returns false when it was left.
  bool stop(std::chrono::milliseconds grace = std::chrono::milliseconds(1500)) noexcept;

 private:
  struct Shared;
  std::shared_ptr<Shared> shared_;
  std::thread thread_;
};

}  // namespace rcand::plugins::vision
