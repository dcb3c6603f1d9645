#include "libs/base/worker_thread.hpp"

#include <pthread.h>
#include <boost/asio/post.hpp>

#include "libs/base/logging.hpp"
#include "libs/base/stop_path_priority.hpp"

namespace rcand {

WorkerThread::WorkerThread(std::string name, std::function<void(const std::string&)> on_error, Priority priority)
    : name_(std::move(name)), on_error_(std::move(on_error)), work_(io_.get_executor()) {
  thread_ = std::thread([this, priority] {
    if (priority == Priority::Background) enter_background_policy();
    run();
  });
}

WorkerThread::~WorkerThread() { join(); }

void WorkerThread::run() noexcept {
  // Linux thread names are at most 15 characters; enough to tell workers apart in top and gdb.
  pthread_setname_np(pthread_self(), name_.substr(0, 15).c_str());
  // Tasks are guarded one by one (run_guarded); an I/O handler given straight to the context is guarded here. After
  // a throw, asio lets run() go on where it left off.
  for (;;) {
    try {
      io_.run();
      return;
    } catch (const std::exception& e) {
      report("handler", e.what());
    } catch (...) {
      report("handler", "non-standard exception");
    }
  }
}

void WorkerThread::report(const char* what, const std::string& why) noexcept {
  try {
    logger("kernel.workers")->error("worker {}: {} threw: {}", name_, what, why);
    if (on_error_) on_error_(why);
  } catch (...) {  // nothing left to tell; the loop goes on
  }
}

void WorkerThread::run_guarded(const std::function<void()>& task) noexcept {
  try {
    task();
  } catch (const std::exception& e) {
    report("task", e.what());
  } catch (...) {
    report("task", "non-standard exception");
  }
}

void WorkerThread::post(std::function<void()> task) {
  boost::asio::post(io_, [this, task = std::move(task)] { run_guarded(task); });
}

sdk::TimerId WorkerThread::schedule(std::chrono::microseconds delay, std::function<void()> task) {
  auto timer = std::make_shared<boost::asio::steady_timer>(io_, delay);
  sdk::TimerId id;
  {
    std::lock_guard lock(timers_mutex_);
    id = next_id_++;
    timers_.emplace(id, timer);
  }
  timer->async_wait([this, id, timer, task = std::move(task)](const boost::system::error_code& ec) {
    bool still_scheduled;
    {
      std::lock_guard lock(timers_mutex_);
      still_scheduled = timers_.erase(id) > 0;
    }
    // cancel() erases the id first, so an expiry already queued when cancel() ran never runs the task.
    if (!ec && still_scheduled) run_guarded(task);
  });
  return id;
}

bool WorkerThread::cancel(sdk::TimerId id) noexcept {
  std::shared_ptr<boost::asio::steady_timer> timer;
  {
    std::lock_guard lock(timers_mutex_);
    auto it = timers_.find(id);
    if (it == timers_.end()) return false;
    timer = it->second;
    timers_.erase(it);
  }
  // steady_timer is not thread-safe, so the cancel itself runs on the worker; the erase above already decided.
  boost::asio::post(io_, [timer] { timer->cancel(); });
  return true;
}

void WorkerThread::join() {
  if (!thread_.joinable()) return;
  {
    std::lock_guard lock(timers_mutex_);
    for (auto& [id, timer] : timers_) boost::asio::post(io_, [timer = timer] { timer->cancel(); });
    timers_.clear();
  }
  end_thread();
}

void WorkerThread::stop_after_queued() noexcept {
  if (!thread_.joinable()) return;
  try {
    boost::asio::post(io_, [this] { io_.stop(); });
  } catch (...) {  // no memory for the posted stop: stop at once instead
    io_.stop();
  }
  end_thread();
}

void WorkerThread::stop() noexcept {
  if (!thread_.joinable()) return;
  io_.stop();
  end_thread();
}

void WorkerThread::end_thread() noexcept {
  work_.reset();
  // A task that ends its own worker cannot wait for itself: the loop ends after it, the owner's join() reaps it.
  if (std::this_thread::get_id() == thread_.get_id()) return;
  thread_.join();
}

}  // namespace rcand
