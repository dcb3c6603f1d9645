#include "libs/base/worker_thread.hpp"

#include <pthread.h>
#include <boost/asio/post.hpp>

#include "libs/base/logging.hpp"

namespace rcand {

WorkerThread::WorkerThread(std::string name, std::function<void(const std::string&)> on_error)
    : name_(std::move(name)), on_error_(std::move(on_error)), work_(io_.get_executor()) {
  thread_ = std::thread([this] {
    // Linux thread names are at most 15 characters; enough to tell workers apart in top and gdb.
    pthread_setname_np(pthread_self(), name_.substr(0, 15).c_str());
    io_.run();
  });
}

WorkerThread::~WorkerThread() { join(); }

void WorkerThread::run_guarded(const std::function<void()>& task) noexcept {
  try {
    task();
  } catch (const std::exception& e) {
    logger("kernel.workers")->error("worker {}: task threw: {}", name_, e.what());
    if (on_error_) on_error_(e.what());
  } catch (...) {
    logger("kernel.workers")->error("worker {}: task threw a non-standard exception", name_);
    if (on_error_) on_error_("non-standard exception");
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
  work_.reset();
  thread_.join();
}

}  // namespace rcand
