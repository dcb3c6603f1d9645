// rcand's one executor: an asio io_context run by one dedicated, named thread (sdk::Worker for plugins; the
// kernel's timers and handler workers; the R2R transports, the R2R clock and the swarm fan-out).
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
  // Starts the thread, named `name` (Linux keeps the first 15 characters). `on_error` runs on this thread when a
  // task or an I/O handler throws, after the throw is logged (the kernel marks the owning instance failed); the
  // loop goes on either way, so one bad task or message never silences the thread.
  // Background: SCHED_BATCH at nice 10 (enter_background_policy), for follow-up work that must not compete with stops
  // on saturated cores (the status board, the R2R clock).
  enum class Priority { Normal, Background };
  WorkerThread(std::string name, std::function<void(const std::string&)> on_error, Priority priority = Priority::Normal);
  ~WorkerThread() override;  // join()
  WorkerThread(const WorkerThread&) = delete;
  WorkerThread& operator=(const WorkerThread&) = delete;

  std::string_view name() const noexcept override { return name_; }
  void post(std::function<void()> task) override;
  sdk::TimerId schedule(std::chrono::microseconds delay, std::function<void()> task) override;
  bool cancel(sdk::TimerId id) noexcept override;

  // Three ways to end, each joining the thread (idempotent, and any of them makes the others no-ops):
  // join(): cancels pending timers and lets everything else finish: queued tasks and I/O still in progress.
  void join();
  // stop_after_queued(): runs the tasks queued so far (a transport's closes), then stops; what they leave pending
  // (I/O, timers, later tasks) is abandoned and destroyed with the worker.
  void stop_after_queued() noexcept;
  // stop(): stops once the handler running now returns; everything queued or pending is abandoned.
  void stop() noexcept;

  // For I/O objects (sockets, streams, timers) whose handlers must run on this thread.
  boost::asio::io_context& context() noexcept { return io_; }

 private:
  void run() noexcept;
  void run_guarded(const std::function<void()>& task) noexcept;
  void report(const char* what, const std::string& why) noexcept;
  void end_thread() noexcept;

  std::string name_;
  std::function<void(const std::string&)> on_error_;
  boost::asio::io_context io_{1};  // one thread runs it
  boost::asio::executor_work_guard<boost::asio::io_context::executor_type> work_;
  std::mutex timers_mutex_;  // guards timers_ and next_id_ (this worker's own state only)
  std::map<sdk::TimerId, std::shared_ptr<boost::asio::steady_timer>> timers_;
  sdk::TimerId next_id_ = 1;
  std::thread thread_;
};

}  // namespace rcand
