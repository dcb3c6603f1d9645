#include "brain_pool.hpp"

#include <string>

namespace rcand::plugins::chat {

BrainPool::BrainPool(sdk::PluginContext& ctx, std::size_t workers, std::size_t queue_limit) : queue_limit_(queue_limit) {
  for (std::size_t i = 0; i < std::max<std::size_t>(1, workers); ++i)
    workers_.push_back(&ctx.worker("brain-" + std::to_string(i)));
  busy_.assign(workers_.size(), false);
}

BrainPool::Admission BrainPool::submit(std::shared_ptr<Job> job) {
  std::lock_guard lock(mutex_);
  if (stopped_) return Admission::Stopped;
  if (running_.size() + queue_.size() >= capacity()) return Admission::Full;
  queue_.push_back(std::move(job));
  for (std::size_t i = 0; i < workers_.size(); ++i)
    if (!busy_[i]) {
      busy_[i] = true;
      workers_[i]->post([this, i] { drain(i); });
      break;
    }
  return Admission::Queued;
}

// One worker takes jobs until none wait. Never throws: a throwing task would mark the plugin failed.
void BrainPool::drain(std::size_t worker) noexcept {
  for (;;) {
    std::shared_ptr<Job> job;
    {
      std::lock_guard lock(mutex_);
      if (queue_.empty()) {
        busy_[worker] = false;
        return;
      }
      job = std::move(queue_.front());
      queue_.pop_front();
      running_.insert(job);
    }
    try {
      job->run(job->cancel);
    } catch (...) {  // run() answers its client itself; an escape here would take the plugin down
    }
    std::lock_guard lock(mutex_);
    running_.erase(job);
  }
}

void BrainPool::cancel_all(std::uint64_t epoch) noexcept { drop_all(false, epoch); }

void BrainPool::drop_all(bool stopping, std::uint64_t epoch) noexcept {
  std::deque<std::shared_ptr<Job>> dropped;
  std::vector<sdk::CancelToken> tokens;
  {
    std::lock_guard lock(mutex_);
    std::deque<std::shared_ptr<Job>> kept;
    for (auto& job : queue_) (job->epoch < epoch ? dropped : kept).push_back(std::move(job));
    queue_.swap(kept);
    for (const auto& job : running_)
      if (job->epoch < epoch) tokens.push_back(job->cancel);
  }
  for (auto& token : tokens) token.cancel();
  for (auto& job : dropped) {
    job->cancel.cancel();
    try {
      if (job->drop) job->drop(stopping);
    } catch (...) {  // the client is gone; nothing to answer
    }
  }
}

void BrainPool::stop() noexcept {
  {
    std::lock_guard lock(mutex_);
    stopped_ = true;
  }
  drop_all(true, std::numeric_limits<std::uint64_t>::max());
}

BrainPool::Counts BrainPool::counts() const {
  std::lock_guard lock(mutex_);
  return {running_.size(), queue_.size()};
}

}  // namespace rcand::plugins::chat
