#include "bus_worker.hpp"

namespace rcand::plugins::pca9685 {

BusWorker::BusWorker(std::shared_ptr<I2cBus> bus) : state_(std::make_shared<State>()) {
  state_->bus = std::move(bus);
  thread_ = std::thread(loop, state_);
}

BusWorker::~BusWorker() {
  std::unique_lock lock(state_->mutex);
  state_->stopping = true;
  for (auto& queued : state_->queue) queued.ticket->finished = true;  // Dropped
  state_->queue.clear();
  state_->changed.notify_all();
  const bool exited = state_->changed.wait_for(lock, std::chrono::seconds(1), [&] { return state_->exited; });
  lock.unlock();
  if (exited) thread_.join();
  else thread_.detach();  // stuck in a transfer; it owns a reference to the state and the bus
}

void BusWorker::loop(std::shared_ptr<State> state) {
  std::unique_lock lock(state->mutex);
  for (;;) {
    state->changed.wait(lock, [&] { return state->stopping || !state->queue.empty(); });
    if (state->stopping) break;
    Queued next = std::move(state->queue.front());
    state->queue.pop_front();
    lock.unlock();
    Outcome outcome = Outcome::Done;
    std::exception_ptr error;
    try {
      next.job(*state->bus);
    } catch (...) {
      outcome = Outcome::Failed;
      error = std::current_exception();
    }
    lock.lock();
    next.ticket->finished = true;
    next.ticket->outcome = outcome;
    next.ticket->error = error;
    state->changed.notify_all();
  }
  state->exited = true;
  state->changed.notify_all();
}

BusWorker::Result BusWorker::submit(Job job, std::chrono::microseconds deadline, bool first) {
  auto ticket = std::make_shared<Ticket>();
  std::unique_lock lock(state_->mutex);
  if (state_->stopping) return {Outcome::Dropped, nullptr};
  if (first) {
    for (auto& queued : state_->queue) queued.ticket->finished = true;  // Dropped
    state_->queue.clear();
    state_->queue.push_front({std::move(job), ticket});
  } else {
    state_->queue.push_back({std::move(job), ticket});
  }
  state_->changed.notify_all();
  if (!state_->changed.wait_for(lock, deadline, [&] { return ticket->finished; })) return {Outcome::TimedOut, nullptr};
  return {ticket->outcome, ticket->error};
}

BusWorker::Result BusWorker::run(Job job, std::chrono::microseconds deadline) { return submit(std::move(job), deadline, false); }

BusWorker::Result BusWorker::urgent(Job job, std::chrono::microseconds deadline) {
  return submit(std::move(job), deadline, true);
}

}  // namespace rcand::plugins::pca9685
