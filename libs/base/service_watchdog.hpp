// Feeds systemd's watchdog (WatchdogSec=) while a liveness check passes: every half interval it asks `alive`, and
// sends WATCHDOG=1 only when it says yes. A hung e-stop path therefore stops the keep-alives, and systemd restarts
// the service (WatchdogSignal=SIGTERM: the shutdown path latches the e-stop and halts the motors first; the latch
// is persisted, so the restarted robot starts latched). Without a watchdog interval it does nothing.
#pragma once

#include <chrono>
#include <condition_variable>
#include <functional>
#include <mutex>
#include <thread>

namespace rcand {

class ServiceWatchdog {
 public:
  // `alive(within)`: whether the watched path answers within `within` (a quarter of the interval).
  ServiceWatchdog(std::chrono::microseconds interval, std::function<bool(std::chrono::milliseconds within)> alive);
  ~ServiceWatchdog();  // stops and joins
  ServiceWatchdog(const ServiceWatchdog&) = delete;
  ServiceWatchdog& operator=(const ServiceWatchdog&) = delete;

 private:
  void run();

  std::chrono::microseconds interval_;
  std::function<bool(std::chrono::milliseconds)> alive_;
  std::mutex mutex_;
  std::condition_variable wake_;
  bool stopping_ = false;
  std::thread thread_;
};

}  // namespace rcand
