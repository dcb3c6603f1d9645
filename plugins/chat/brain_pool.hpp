// chat's own bounded pool for brain calls, so a brain never holds a kernel thread or the capability's worker: the
// POST /api/command handler only checks the body and submits here. At most `workers` calls run (each on a worker
// thread of chat's own, "chat.brain-<n>", which the kernel joins at shutdown) and at most `queue_limit` wait; a
// submission beyond that is refused at once (the caller answers 429). cancel_all() - the e-stop, shutdown - drops
// every waiting job (its `drop` answers the client) and cancels the running ones through their CancelToken.
#pragma once

#include <rcand/sdk/context.hpp>
#include <rcand/sdk/interfaces/brain.hpp>

#include <cstdint>
#include <deque>
#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <set>
#include <vector>

namespace rcand::plugins::chat {

class BrainPool {
 public:
  struct Job {
    std::function<void(const sdk::CancelToken&)> run;  // on a pool worker; answers the client itself
    std::function<void(bool stopping)> drop;           // dropped before it ran (e-stop, or shutdown when `stopping`)
    sdk::CancelToken cancel;
    std::uint64_t epoch = 0;  // the e-stop epoch it came in under: cancel_all() reaches only jobs of older epochs
  };
  enum class Admission { Queued, Full, Stopped };

  BrainPool(sdk::PluginContext& ctx, std::size_t workers, std::size_t queue_limit);

  // Any thread, never blocks beyond a brief lock.
  Admission submit(std::shared_ptr<Job> job);
  // Any thread, never blocks: drops the waiting jobs that came in before `epoch` (their drop() runs here) and
  // cancels the running ones; jobs of `epoch` or later (after the e-stop was cleared) go on.
  void cancel_all(std::uint64_t epoch) noexcept;
  // cancel_all(), and every later submit() answers Stopped.
  void stop() noexcept;

  struct Counts {
    std::size_t running = 0, queued = 0;
  };
  Counts counts() const;
  std::size_t capacity() const noexcept { return workers_.size() + queue_limit_; }

 private:
  void drain(std::size_t worker) noexcept;
  void drop_all(bool stopping, std::uint64_t epoch) noexcept;

  std::vector<sdk::Worker*> workers_;
  const std::size_t queue_limit_;
  mutable std::mutex mutex_;
  std::deque<std::shared_ptr<Job>> queue_;
  std::set<std::shared_ptr<Job>> running_;
  std::vector<bool> busy_;
  bool stopped_ = false;
};

}  // namespace rcand::plugins::chat
