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

namespace rcand::kernel {

// Runs fn() on a new thread named `thread_name`; true when it returned within `timeout`.
template <class Fn> bool bounded_call(const std::string& thread_name, std::chrono::milliseconds timeout, Fn fn) {
  struct Finish {
    std::mutex mutex;
    std::condition_variable cv;
    bool done = false;
  };
  auto finish = std::make_shared<Finish>();
  std::thread([finish, fn = std::move(fn), name = thread_name.substr(0, 15)]() mutable {
    pthread_setname_np(pthread_self(), name.c_str());
    fn();
    std::lock_guard lock(finish->mutex);
    finish->done = true;
    finish->cv.notify_all();
  }).detach();
  std::unique_lock lock(finish->mutex);
  return finish->cv.wait_for(lock, timeout, [&] { return finish->done; });
}

}  // namespace rcand::kernel
