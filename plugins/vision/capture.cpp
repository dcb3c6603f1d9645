#include "capture.hpp"

#include <pthread.h>

#include <algorithm>

namespace rcand::plugins::vision {

// Everything the thread uses, owned jointly with it: a thread left behind at shutdown still finds it alive.
struct Capture::Shared {
  SourceFactory factory;
  CaptureOptions options;
  std::shared_ptr<FrameHub> hub;
  std::function<void(bool, const std::string&)> report;
  std::mutex mutex;
  std::condition_variable changed;
  bool stopping = false, finished = false;

  // Sleeps until `until` or stop(); true when stopping.
  template <class TimePoint> bool sleep_until(TimePoint until) {
    std::unique_lock lock(mutex);
    return changed.wait_until(lock, until, [&] { return stopping; });
  }
  bool stopping_now() {
    std::lock_guard lock(mutex);
    return stopping;
  }
  // Under the mutex and never once stopping: a thread left behind in a hanging open() or read() comes back after
  // stop() returned, when `report` (which logs through the plugin's context) may point at freed memory.
  void tell(bool fault, const std::string& text) {
    std::lock_guard lock(mutex);
    if (report && !stopping) report(fault, text);
  }

  // Reads until the source fails (returns why) or stop() (returns empty).
  std::string stream(FrameSource& source) {
    using Clock = std::chrono::steady_clock;
    const bool paced = source.paced();
    const auto period =
        std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / std::max(0.1, source.fps())));
    auto due = Clock::now();
    while (true) {
      if (paced) {
        if (sleep_until(due)) return {};
        due += period;
        if (due < Clock::now() - period) due = Clock::now();  // after a hiccup: no burst of catch-up frames
      } else if (stopping_now()) {
        return {};
      }
      if (source.skip_when_unwatched() && !hub->wanted()) {
        hub->alive();
        continue;
      }
      CameraFrame frame;
      try {
        if (!source.read_frame(frame)) return source.describe() + " stopped delivering frames";
      } catch (const std::exception& e) {
        return e.what();
      }
      if (stopping_now()) return {};
      hub->frame(std::move(frame));
    }
  }

  void run() {
    auto backoff = options.reconnect_min;
    std::string fault;
    while (!stopping_now()) {
      std::unique_ptr<FrameSource> source;
      std::string why;
      try {
        source = factory();
        source->open();
      } catch (const std::exception& e) {
        why = e.what();
      }
      const bool opened = why.empty();
      if (opened) {
        hub->source_opened(source->describe(), source->fps());
        if (!fault.empty()) tell(false, "camera back: " + source->describe());
        fault.clear();
        backoff = options.reconnect_min;
        why = stream(*source);
        if (why.empty()) break;  // stopping
      }
      source.reset();
      hub->source_lost(why);
      if (why != fault)
        tell(true, why + "; reconnecting (backoff up to " + std::to_string(options.reconnect_max.count()) + " ms)");
      fault = why;
      const auto delay = backoff;
      if (!opened) backoff = std::min(backoff * 2, options.reconnect_max);
      if (sleep_until(std::chrono::steady_clock::now() + delay)) break;
    }
    std::lock_guard lock(mutex);
    finished = true;
    changed.notify_all();
  }
};

Capture::Capture(SourceFactory factory, CaptureOptions options, std::shared_ptr<FrameHub> hub,
                 std::function<void(bool, const std::string&)> report)
    : shared_(std::make_shared<Shared>()) {
  shared_->factory = std::move(factory);
  options.reconnect_min = std::min(options.reconnect_min, options.reconnect_max);
  shared_->options = options;
  shared_->hub = std::move(hub);
  shared_->report = std::move(report);
}

Capture::~Capture() { stop(); }

void Capture::start() {
  if (thread_.joinable()) return;
  thread_ = std::thread([shared = shared_] {
    ::pthread_setname_np(::pthread_self(), "vision.capture");
    shared->run();
  });
}

bool Capture::stop(std::chrono::milliseconds grace) noexcept {
  if (!thread_.joinable()) return true;
  std::unique_lock lock(shared_->mutex);
  shared_->stopping = true;
  shared_->changed.notify_all();
  const bool finished = shared_->changed.wait_for(lock, grace, [&] { return shared_->finished; });
  lock.unlock();
  if (finished) thread_.join();
  else thread_.detach();
  return finished;
}

}  // namespace rcand::plugins::vision
