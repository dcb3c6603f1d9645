// A call into plugin code that may never return, waited for up to a timeout. Plugin code cannot be interrupted, so
// a call that overruns is left running on its own thread: `fn` must own (or share) everything it touches.
#pragma once

#include <chrono>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include <pthread.h>

namespace rcand {

// What a bounded_call waits on. give_up() (any thread) ends every wait on it now and later, as if the call overran:
// a shutdown does not wait out a plugin's start.
struct CallWaiter {
  std::mutex mutex;
  std::condition_variable cv;
  bool given_up = false;
  void give_up() {
    {
      std::lock_guard lock(mutex);
      given_up = true;
    }
    cv.notify_all();
  }
};

// Runs fn() on a new thread named `thread_name`; true when it returned within `timeout` (and `waiter` was not given
// up on).
template <class Fn>
bool bounded_call(const std::string& thread_name, std::chrono::milliseconds timeout, Fn fn,
                  std::shared_ptr<CallWaiter> waiter = std::make_shared<CallWaiter>()) {
  auto done = std::make_shared<bool>(false);  // under waiter->mutex
  std::thread([waiter, done, fn = std::move(fn), name = thread_name.substr(0, 15)]() mutable {
    pthread_setname_np(pthread_self(), name.c_str());
    fn();
    {
      std::lock_guard lock(waiter->mutex);
      *done = true;
    }
    waiter->cv.notify_all();
  }).detach();
  std::unique_lock lock(waiter->mutex);
  waiter->cv.wait_for(lock, timeout, [&] { return *done || waiter->given_up; });
  return *done;
}

}  // namespace rcand
