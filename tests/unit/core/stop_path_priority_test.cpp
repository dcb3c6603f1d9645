#include <doctest/doctest.h>
#include <pthread.h>
#include <sched.h>
#include <sys/resource.h>
#include <unistd.h>

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

TEST_CASE("the stop's follow-up threads: batch (never preempts on wake-up), background also at nice 10") {
  int batch_policy = -1, background_policy = -1, background_nice = 0;
  bool batch_ok = false, background_ok = false;
  std::thread([&] {
    batch_ok = rcand::enter_batch_policy();
    sched_param param{};
    pthread_getschedparam(pthread_self(), &batch_policy, &param);
  }).join();
  std::thread([&] {
    background_ok = rcand::enter_background_policy();
    sched_param param{};
    pthread_getschedparam(pthread_self(), &background_policy, &param);
    background_nice = getpriority(PRIO_PROCESS, static_cast<id_t>(::gettid()));
  }).join();
  CHECK(batch_ok);
  CHECK(batch_policy == SCHED_BATCH);
  CHECK(background_ok);
  CHECK(background_policy == SCHED_BATCH);
  CHECK(background_nice == 10);
}
