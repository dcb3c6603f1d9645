// sdk::Worker on one dedicated thread (an asio io_context), named and joined by the kernel.
#pragma once

#include <boost/asio/executor_work_guard.hpp>
#include <boost/asio/io_context.hpp>
#include <boost/asio/steady_timer.hpp>

#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "rcand/sdk/worker.hpp"

namespace rcand {

class WorkerThread final : public sdk::Worker {
 public:
  // `on_error` runs on this thread when a task throws (the kernel marks the owning instance failed).
  WorkerThread(std::string name, std::function<void(const std::string&)> on_error);
  ~WorkerThread() override;  // join()
  WorkerThread(const WorkerThread&) = delete;
  WorkerThread& operator=(const WorkerThread&) = delete;

  std::string_view name() const noexcept override { return name_; }
  void post(std::function<void()> task) override;
  sdk::TimerId schedule(std::chrono::microseconds delay, std::function<void()> task) override;
  bool cancel(sdk::TimerId id) noexcept override;

  // Cancels pending timers, lets queued tasks finish, joins the thread. Idempotent.
  void join();
  boost::asio::io_context& context() noexcept { return io_; }

 private:
  void run_guarded(const std::function<void()>& task) noexcept;

  std::string name_;
  std::function<void(const std::string&)> on_error_;
  boost::asio::io_context io_;
  boost::asio::executor_work_guard<boost::asio::io_context::executor_type> work_;
  std::mutex timers_mutex_;  // guards timers_ and next_id_ (this worker's own state only)
  std::map<sdk::TimerId, std::shared_ptr<boost::asio::steady_timer>> timers_;
  sdk::TimerId next_id_ = 1;
  std::thread thread_;
};

}  // namespace rcand
