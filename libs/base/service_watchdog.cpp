#include "libs/base/service_watchdog.hpp"

#include <pthread.h>

#include "libs/base/logging.hpp"
#include "libs/base/systemd_notify.hpp"

namespace rcand {

ServiceWatchdog::ServiceWatchdog(std::chrono::microseconds interval, std::function<bool(std::chrono::milliseconds)> alive)
    : interval_(interval), alive_(std::move(alive)), thread_([this] { run(); }) {}

ServiceWatchdog::~ServiceWatchdog() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  thread_.join();
}

void ServiceWatchdog::run() {
  pthread_setname_np(pthread_self(), "sd.watchdog");
  const auto period = interval_ / 2;
  const auto within = std::chrono::duration_cast<std::chrono::milliseconds>(interval_ / 4);
  bool failing = false;
  std::unique_lock lock(mutex_);
  while (!wake_.wait_for(lock, period, [this] { return stopping_; })) {
    lock.unlock();
    const bool ok = alive_(within);
    if (ok) notify_service_manager("WATCHDOG=1");
    if (ok == failing) {  // log the change only, not every period
      failing = !ok;
      if (failing)
        logger("kernel")->error("the e-stop path did not answer within {} ms: not feeding the service watchdog", within.count());
      else logger("kernel")->warn("the e-stop path answers again: feeding the service watchdog");
    }
    lock.lock();
  }
}

}  // namespace rcand
