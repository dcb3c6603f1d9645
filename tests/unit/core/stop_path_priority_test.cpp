#include <doctest/doctest.h>
#include <pthread.h>
#include <sched.h>

#include <string>
#include <thread>

#include "libs/base/stop_path_priority.hpp"

using rcand::enter_stop_path_priority;

namespace {

struct SeenPolicy {
  std::string result;
  int policy = -1, priority = -1;
};

SeenPolicy stop_path_thread(int priority) {
  SeenPolicy seen;
  std::thread([&] {
    seen.result = enter_stop_path_priority(priority);
    sched_param param{};
    pthread_getschedparam(pthread_self(), &seen.policy, &param);
    seen.priority = param.sched_priority;
  }).join();
  return seen;
}

}  // namespace

TEST_CASE("stop path priority 0 leaves the thread's scheduling alone") {
  const auto seen = stop_path_thread(0);
  CHECK(seen.result.empty());
  CHECK(seen.policy == SCHED_OTHER);
}

TEST_CASE("stop path priority: SCHED_FIFO at that priority, or a reason naming the fix") {
  const auto seen = stop_path_thread(10);
  if (seen.result.empty()) {
    CHECK(seen.policy == SCHED_FIFO);
    CHECK(seen.priority == 10);
  } else {  // not permitted here (a container without CAP_SYS_NICE): said, not silent
    CHECK(seen.policy == SCHED_OTHER);
    CHECK(seen.result.find("runtime.stop_path_priority 10") != std::string::npos);
    CHECK(seen.result.find("LimitRTPRIO=10") != std::string::npos);
  }
}
