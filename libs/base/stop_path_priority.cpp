#include "libs/base/stop_path_priority.hpp"

#include <pthread.h>
#include <sched.h>
#include <sys/resource.h>
#include <unistd.h>

#include <atomic>
#include <cstring>

#include "libs/base/logging.hpp"

namespace rcand {

std::string enter_stop_path_priority(int priority) noexcept {
  if (priority <= 0) return {};
  try {
    sched_param param{};
    param.sched_priority = priority;
    const int error = pthread_setschedparam(pthread_self(), SCHED_FIFO, &param);
    if (error == 0) return {};
    std::string why = "runtime.stop_path_priority " + std::to_string(priority) + ": cannot make the stop path real-time (" +
                      std::strerror(error) +
                      "); stops share the CPU with all other work. Allow it with LimitRTPRIO=" + std::to_string(priority) +
                      " (systemd) or CAP_SYS_NICE, or set it to 0";
    static std::atomic<bool> warned{false};
    if (!warned.exchange(true)) logger("kernel")->warn("{}", why);
    return why;
  } catch (...) {
    return "out of memory";
  }
}

bool enter_batch_policy() noexcept {
  sched_param param{};
  return pthread_setschedparam(pthread_self(), SCHED_BATCH, &param) == 0;
}

bool enter_background_policy() noexcept {
  const bool batch = enter_batch_policy();
  return setpriority(PRIO_PROCESS, static_cast<id_t>(::gettid()), 10) == 0 && batch;
}

}  // namespace rcand
