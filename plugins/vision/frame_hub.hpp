// Between one camera and its viewers. The capture thread hands every frame in; the hub's own delivery thread
// encodes it ONCE to JPEG - only when someone watches or waits for a snapshot - and pushes the same bytes (shared, never
// copied per viewer) to every viewer whose ?fps= lets it have this frame. The writers hold at most one pending frame
// per viewer (rcand/sdk/stream.hpp), so a slow viewer skips frames and never holds up the others or this thread.
//
// When the capture thread reports the source lost, or no frame arrived for two frame periods (at least
// signal_timeout, 250 ms), the hub delivers generated NO SIGNAL frames instead (at no_signal_fps) - never the last
// picture again - and its status says why in a top-level "fault", which the kernel shows as the capability's state
// "error" in GET /api/status and telemetry (sdk/capability.hpp), until frames come again.
#pragma once

#include <rcand/sdk/stream.hpp>

#include <opencv2/core.hpp>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "camera_source.hpp"

namespace rcand::plugins::vision {

// Encodes one frame. The hub counts its calls: one per delivered frame, however many viewers.
using Encoder = std::function<sdk::SharedBytes(const cv::Mat&)>;
Encoder jpeg_encoder(int quality);

struct HubOptions {
  std::size_t max_viewers = 32;
  // Of max_viewers, the last ones only for viewers add_viewer is told are operators; at most max_viewers - 1, so
  // anyone may always watch when nobody else does.
  std::size_t reserved_viewers = 4;
  std::chrono::milliseconds signal_timeout{250};  // no frame for this long (or 2 frame periods, if longer): NO SIGNAL
  double no_signal_fps = 5.0;
  int width = 640, height = 480;  // of NO SIGNAL frames until the camera delivered one
  std::string source = "camera";  // what the status calls it until the source opened
};

class FrameHub {
 public:
  // `publish` receives the status on change (at most 10 times a second) and about once a second while viewers watch,
  // on the delivery thread.
  FrameHub(HubOptions options, Encoder encoder, std::function<void(const sdk::Json&)> publish = {});
  ~FrameHub();
  FrameHub(const FrameHub&) = delete;
  FrameHub& operator=(const FrameHub&) = delete;

  void start();
  void stop() noexcept;  // joins the delivery thread; viewers' streams end

  // ---- the capture thread (never blocks beyond a brief lock) ----
  void frame(cv::Mat image);
  // A frame that may be the camera's own JPEG (CameraFrame): delivered as it is, never encoded again.
  void frame(CameraFrame frame);
  void alive();  // a frame was due but skipped (nobody watches a synthetic source): the camera is not stalled
  void source_opened(const std::string& description, double fps);
  void source_lost(const std::string& reason);
  bool wanted() const;  // someone watches or waits for a snapshot

  // ---- request handlers ----
  enum class Admission { Admitted, Full, Reserved, Gone };
  // Starts `writer`'s multipart answer and adds the viewer; Full: max_viewers already watch; Reserved: only the
  // reserved places are left and `operator_role` is false (nothing was answered either way).
  Admission add_viewer(const std::shared_ptr<sdk::StreamWriter>& writer, std::optional<double> max_fps, std::string who,
                       bool operator_role = true);
  // The next frame (a NO SIGNAL one while the camera is down) is sent to `writer` as one image/jpeg.
  void add_snapshot(std::shared_ptr<sdk::StreamWriter> writer);
  sdk::Json status() const;
  std::size_t max_viewers() const noexcept { return options_.max_viewers; }
  std::size_t reserved_places() const noexcept {
    return std::min(options_.reserved_viewers, options_.max_viewers > 0 ? options_.max_viewers - 1 : 0);
  }

  // ---- observation (tests, bench) ----
  struct Counts {
    std::uint64_t captured = 0;  // frames the capture thread handed in
    std::uint64_t encoded = 0;   // encoder calls
    std::uint64_t passed = 0;    // camera JPEGs delivered as they are (no encoder call)
    std::uint64_t rounds = 0;    // deliveries made (a frame pushed to someone)
  };
  Counts counts() const;
  // Waits until `done(counts())`, woken by every frame and delivery; false at the limit.
  bool wait(const std::function<bool(const Counts&)>& done, std::chrono::milliseconds limit) const;

 private:
  struct Viewer;
  struct Delivery;
  using Clock = std::chrono::steady_clock;

  void run();
  // What to deliver now, if anything; else when to look again. Called with mutex_ held.
  std::optional<Delivery> next_delivery(Clock::time_point now, Clock::time_point& wake);
  void deliver(Delivery& delivery);
  void update_stats(Clock::time_point now);  // mutex_ held
  sdk::Json status_locked() const;
  void set_signal(bool live, std::string reason);  // mutex_ held

  const HubOptions options_;
  const Encoder encoder_;
  const std::function<void(const sdk::Json&)> publish_;

  mutable std::mutex mutex_;
  mutable std::condition_variable wake_;
  mutable std::condition_variable delivered_;
  bool stopping_ = false, dirty_ = true;
  std::thread thread_;

  // The newest frame, shared with the delivery in progress.
  std::shared_ptr<const cv::Mat> latest_;
  std::shared_ptr<const std::string> latest_jpeg_;  // set: the newest frame is the camera's own JPEG (latest_ null)
  cv::Size latest_size_;                            // of the newest frame; empty before the first
  std::uint64_t latest_seq_ = 0, delivered_seq_ = 0;
  std::int64_t latest_us_ = 0, latest_wall_ms_ = 0;  // steady (comparable across processes) and wall time of capture
  Clock::time_point alive_at_;                       // the capture thread's last sign of life
  Clock::time_point last_no_signal_{}, published_at_{};
  std::chrono::milliseconds stall_after_;

  // The camera, as the status shows it.
  std::string source_, state_ = "starting", fault_;
  double source_fps_ = 0;
  std::int64_t state_since_ms_ = 0;
  std::uint64_t reconnects_ = 0;
  bool live_ = true;

  std::vector<std::shared_ptr<Viewer>> viewers_;
  std::vector<std::shared_ptr<sdk::StreamWriter>> snapshots_;
  std::uint64_t next_viewer_id_ = 1;

  std::uint64_t captured_ = 0, encoded_ = 0, passed_ = 0, rounds_ = 0;
  std::uint64_t stats_captured_ = 0, stats_encoded_ = 0, stats_passed_ = 0;
  double captured_fps_ = 0, encoded_fps_ = 0, passed_fps_ = 0;
  Clock::time_point stats_at_;
};

}  // namespace rcand::plugins::vision
