#include "frame_hub.hpp"

#include <pthread.h>

#include <algorithm>
#include <cmath>

#include "camera_source.hpp"
#include "jpeg_encoder.hpp"

namespace rcand::plugins::vision {
namespace {

using namespace std::chrono_literals;

constexpr auto kPublishPeriod = std::chrono::milliseconds(100);
// A viewer asking for 15 fps of a 30 fps camera gets every second frame although capture times jitter.
constexpr std::int64_t kIntervalSlackUs = 5000;

std::int64_t steady_us(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration_cast<std::chrono::microseconds>(t.time_since_epoch()).count();
}
std::int64_t wall_ms() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::system_clock::now().time_since_epoch()).count();
}
double tenths(double value) { return std::round(value * 10.0) / 10.0; }

}  // namespace

struct FrameHub::Viewer {
  std::uint64_t id = 0;
  std::shared_ptr<sdk::StreamWriter> writer;
  std::optional<double> max_fps;
  std::int64_t min_interval_us = 0;  // 0: every frame
  std::int64_t last_sent_us = 0;
  std::string who;
  std::int64_t since_ms = 0;
  std::uint64_t stats_sent = 0;
  double fps = 0;
};

struct FrameHub::Delivery {
  std::shared_ptr<const cv::Mat> image;     // null: a NO SIGNAL frame, drawn outside the lock (unless jpeg is set)
  std::shared_ptr<const std::string> jpeg;  // the camera's own JPEG: sent as it is
  std::uint64_t seq = 0;
  std::int64_t captured_us = 0, wall_ms = 0;
  bool live = true;
  std::string reason;
  int width = 0, height = 0;
  std::vector<std::shared_ptr<Viewer>> viewers;
  std::vector<std::shared_ptr<sdk::StreamWriter>> snapshots;
};

// One compressor and output buffer for the hub's frames, kept from frame to frame; the lock only matters if a copy
// of the Encoder runs on another thread.
Encoder jpeg_encoder(int quality) {
  struct Shared {
    std::mutex mutex;
    JpegEncoder jpeg;
  };
  return [quality, shared = std::make_shared<Shared>()](const cv::Mat& image) -> sdk::SharedBytes {
    std::lock_guard lock(shared->mutex);
    return std::make_shared<const std::string>(shared->jpeg.encode(image, quality));
  };
}

FrameHub::FrameHub(HubOptions options, Encoder encoder, std::function<void(const sdk::Json&)> publish)
    : options_(std::move(options)),
      encoder_(std::move(encoder)),
      publish_(std::move(publish)),
      stall_after_(options_.signal_timeout),
      source_(options_.source) {}

FrameHub::~FrameHub() { stop(); }

void FrameHub::start() {
  std::lock_guard lock(mutex_);
  if (thread_.joinable()) return;
  alive_at_ = stats_at_ = Clock::now();
  state_since_ms_ = wall_ms();
  thread_ = std::thread([this] {
    ::pthread_setname_np(::pthread_self(), "vision.deliver");
    run();
  });
}

void FrameHub::stop() noexcept {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable() && thread_.get_id() != std::this_thread::get_id()) thread_.join();
}

void FrameHub::frame(cv::Mat image) {
  const cv::Size size = image.size();
  frame(CameraFrame{std::move(image), nullptr, size});
}

void FrameHub::frame(CameraFrame camera) {
  auto shared = camera.jpeg ? nullptr : std::make_shared<const cv::Mat>(std::move(camera.image));
  const auto now = Clock::now();
  {
    std::lock_guard lock(mutex_);
    latest_ = std::move(shared);
    latest_jpeg_ = std::move(camera.jpeg);
    latest_size_ = camera.size;
    ++latest_seq_;
    ++captured_;
    latest_us_ = steady_us(now);
    latest_wall_ms_ = wall_ms();
    alive_at_ = now;
    set_signal(true, "");
  }
  wake_.notify_one();
  delivered_.notify_all();
}

void FrameHub::alive() {
  std::lock_guard lock(mutex_);
  alive_at_ = Clock::now();
}

void FrameHub::source_opened(const std::string& description, double fps) {
  std::lock_guard lock(mutex_);
  source_ = description;
  source_fps_ = std::isfinite(fps) && fps > 0 ? fps : 0;
  // Two frame periods: one late frame is jitter, a second missing one is a stall. source_fps_ is 0 or >= 1e-300, so
  // the quotient is finite, but may exceed any integer: capped at a minute before the conversion.
  const double period_ms = source_fps_ > 0 ? std::min(2000.0 / source_fps_, 60'000.0) : 0.0;
  const auto periods = std::chrono::milliseconds(static_cast<std::int64_t>(std::ceil(period_ms)));
  stall_after_ = std::max(options_.signal_timeout, periods);
  alive_at_ = Clock::now();  // from here the first frame has stall_after_ to come
  dirty_ = true;
}

void FrameHub::source_lost(const std::string& reason) {
  {
    std::lock_guard lock(mutex_);
    set_signal(false, reason);
  }
  wake_.notify_one();
}

bool FrameHub::wanted() const {
  std::lock_guard lock(mutex_);
  return !viewers_.empty() || !snapshots_.empty();
}

void FrameHub::set_signal(bool live, std::string reason) {
  if (live ? (live_ && state_ == "live") : (!live_ && reason == fault_)) return;
  if (live && !live_) ++reconnects_;         // back after a loss
  if (!live && live_) last_no_signal_ = {};  // the first NO SIGNAL frame goes out at once
  live_ = live;
  state_ = live ? "live" : "no_signal";
  fault_ = std::move(reason);
  state_since_ms_ = wall_ms();
  dirty_ = true;
}

FrameHub::Admission FrameHub::add_viewer(const std::shared_ptr<sdk::StreamWriter>& writer, std::optional<double> max_fps,
                                         std::string who, bool operator_role) {
  {
    std::lock_guard lock(mutex_);
    if (stopping_) return Admission::Gone;
    std::erase_if(viewers_, [](const auto& v) { return v->writer->closed(); });
    if (viewers_.size() >= options_.max_viewers) return Admission::Full;
    if (!operator_role && viewers_.size() >= options_.max_viewers - reserved_places()) return Admission::Reserved;
    // Started under the lock, so the delivery thread never sees a viewer whose answer has not begun.
    if (!writer->start(200, "multipart/x-mixed-replace", {{"X-Accel-Buffering", "no"}})) return Admission::Gone;
    auto viewer = std::make_shared<Viewer>();
    viewer->id = next_viewer_id_++;
    viewer->writer = writer;
    viewer->max_fps = max_fps;
    viewer->min_interval_us = max_fps ? static_cast<std::int64_t>(1e6 / *max_fps) : 0;
    viewer->last_sent_us = steady_us(Clock::now()) - viewer->min_interval_us;
    viewer->who = std::move(who);
    viewer->since_ms = wall_ms();
    viewers_.push_back(std::move(viewer));
    dirty_ = true;
  }
  wake_.notify_one();
  return Admission::Admitted;
}

void FrameHub::add_snapshot(std::shared_ptr<sdk::StreamWriter> writer) {
  {
    std::lock_guard lock(mutex_);
    if (stopping_) {
      writer->respond(sdk::Response::error(503, "UNAVAILABLE", "the camera is shutting down"));
      return;
    }
    snapshots_.push_back(std::move(writer));
  }
  wake_.notify_one();
}

std::optional<FrameHub::Delivery> FrameHub::next_delivery(Clock::time_point now, Clock::time_point& wake) {
  if (live_ && now - alive_at_ > stall_after_)
    set_signal(false, "no frame from " + source_ + " for " + std::to_string(stall_after_.count()) + " ms");
  if (std::erase_if(viewers_, [](const auto& v) { return v->writer->closed(); }) > 0) dirty_ = true;

  Delivery d;
  if (live_) {
    wake = alive_at_ + stall_after_ + 1ms;  // the stall check
    if ((!latest_ && !latest_jpeg_) || latest_seq_ == delivered_seq_) return std::nullopt;
    delivered_seq_ = latest_seq_;
    d.image = latest_;
    d.jpeg = latest_jpeg_;
    d.seq = latest_seq_;
    d.captured_us = latest_us_;
    d.wall_ms = latest_wall_ms_;
  } else {
    const auto period = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / options_.no_signal_fps));
    if (now - last_no_signal_ < period && snapshots_.empty()) {
      wake = last_no_signal_ + period;
      return std::nullopt;
    }
    wake = now + period;
    if (viewers_.empty() && snapshots_.empty()) return std::nullopt;  // nobody to draw it for
    last_no_signal_ = now;
    d.live = false;
    d.reason = fault_;
    d.captured_us = steady_us(now);
    d.wall_ms = wall_ms();
    d.width = latest_size_.empty() ? options_.width : latest_size_.width;
    d.height = latest_size_.empty() ? options_.height : latest_size_.height;
  }
  for (const auto& viewer : viewers_) {
    if (viewer->min_interval_us > 0 && d.captured_us - viewer->last_sent_us < viewer->min_interval_us - kIntervalSlackUs)
      continue;  // it asked for fewer frames
    viewer->last_sent_us = d.captured_us;
    d.viewers.push_back(viewer);
  }
  d.snapshots.swap(snapshots_);
  if (d.viewers.empty() && d.snapshots.empty()) return std::nullopt;  // nobody watches: no encode
  return d;
}

void FrameHub::deliver(Delivery& d) {
  sdk::SharedBytes jpeg = d.jpeg;
  if (!jpeg) {
    try {
      if (!d.image) d.image = std::make_shared<const cv::Mat>(no_signal_frame(d.width, d.height, d.reason, d.wall_ms));
      jpeg = encoder_(*d.image);
    } catch (...) {  // an encoder failure drops this frame; the next one tries again
    }
  }
  {
    std::lock_guard lock(mutex_);
    ++(d.jpeg ? passed_ : encoded_);
  }
  if (!jpeg) {
    for (auto& snapshot : d.snapshots) snapshot->respond(sdk::Response::error(500, "INTERNAL", "the frame could not be encoded"));
    return;
  }
  const sdk::Headers headers{{"X-Timestamp-Us", std::to_string(d.captured_us)},
                             {"X-Frame", std::to_string(d.seq)},
                             {"X-Signal", d.live ? "live" : "none"}};
  for (auto& viewer : d.viewers) viewer->writer->push({jpeg, "image/jpeg", headers});
  for (auto& snapshot : d.snapshots) {
    sdk::Headers with_cache = headers;
    with_cache.emplace_back("Cache-Control", "no-store");
    if (snapshot->start(200, "image/jpeg", std::move(with_cache))) snapshot->send(jpeg);
  }
}

void FrameHub::update_stats(Clock::time_point now) {
  const double seconds = std::chrono::duration<double>(now - stats_at_).count();
  if (seconds <= 0) return;
  const double captured = tenths((captured_ - stats_captured_) / seconds);
  const double encoded = tenths((encoded_ - stats_encoded_) / seconds);
  const double passed = tenths((passed_ - stats_passed_) / seconds);
  if (captured != captured_fps_ || encoded != encoded_fps_ || passed != passed_fps_ || !viewers_.empty()) dirty_ = true;
  captured_fps_ = captured;
  encoded_fps_ = encoded;
  passed_fps_ = passed;
  stats_captured_ = captured_;
  stats_encoded_ = encoded_;
  stats_passed_ = passed_;
  for (auto& viewer : viewers_) {
    const auto sent = viewer->writer->counters().sent;
    viewer->fps = tenths((sent - viewer->stats_sent) / seconds);
    viewer->stats_sent = sent;
  }
  stats_at_ = now;
}

void FrameHub::run() {
  std::unique_lock lock(mutex_);
  while (!stopping_) {
    const auto now = Clock::now();
    if (now - stats_at_ >= 1s) update_stats(now);
    // Published on change, at most 10 times a second (a burst of viewers joining is one publish, not one each).
    const bool publish_due = dirty_ && publish_ && now - published_at_ >= kPublishPeriod;
    if (publish_due) {
      sdk::Json status = status_locked();
      dirty_ = false;
      published_at_ = now;
      lock.unlock();
      publish_(status);
      lock.lock();
      continue;
    }
    auto wake = now + 1s;
    auto delivery = next_delivery(now, wake);
    if (!delivery) {
      auto until = std::min(wake, stats_at_ + 1s);
      if (dirty_ && publish_) until = std::min(until, published_at_ + kPublishPeriod);
      wake_.wait_until(lock, until);
      continue;
    }
    lock.unlock();
    deliver(*delivery);
    delivery.reset();  // the frame and writers go before the lock is taken again
    lock.lock();
    ++rounds_;
    delivered_.notify_all();
  }
  auto viewers = std::move(viewers_);
  auto snapshots = std::move(snapshots_);
  lock.unlock();
  for (auto& viewer : viewers) viewer->writer->end();
  for (auto& snapshot : snapshots) snapshot->respond(sdk::Response::error(503, "UNAVAILABLE", "the camera is shutting down"));
}

sdk::Json FrameHub::status_locked() const {
  sdk::Json viewers = sdk::Json::array();
  for (const auto& viewer : viewers_) {
    const auto counters = viewer->writer->counters();
    viewers.push_back({{"id", viewer->id},
                       {"who", viewer->who},
                       {"fps", viewer->fps},
                       {"max_fps", viewer->max_fps ? sdk::Json(*viewer->max_fps) : sdk::Json()},
                       {"sent", counters.sent},
                       {"dropped", counters.dropped},
                       {"since_ms", viewer->since_ms}});
  }
  // "fault" at the top: the SDK's convention for "running, but cannot do its job" (the kernel shows state "error").
  return {{"fault", live_ || fault_.empty() ? sdk::Json() : sdk::Json(fault_)},
          {"camera",
           {{"source", source_},
            {"state", state_},
            {"fault", fault_.empty() ? sdk::Json() : sdk::Json(fault_)},
            {"since_ms", state_since_ms_},
            {"fps", tenths(source_fps_)},
            {"reconnects", reconnects_}}},
          {"captured_fps", captured_fps_},
          {"encoded_fps", encoded_fps_},
          {"passed_through_fps", passed_fps_},
          {"frames_captured", captured_},
          {"frames_encoded", encoded_},
          {"frames_passed_through", passed_},
          {"viewers", std::move(viewers)},
          {"max_viewers", options_.max_viewers}};
}

sdk::Json FrameHub::status() const {
  std::lock_guard lock(mutex_);
  return status_locked();
}

FrameHub::Counts FrameHub::counts() const {
  std::lock_guard lock(mutex_);
  return {captured_, encoded_, passed_, rounds_};
}

bool FrameHub::wait(const std::function<bool(const Counts&)>& done, std::chrono::milliseconds limit) const {
  std::unique_lock lock(mutex_);
  return delivered_.wait_for(lock, limit, [&] { return done(Counts{captured_, encoded_, passed_, rounds_}); });
}

}  // namespace rcand::plugins::vision
