#include "serial_worker.hpp"

namespace rcand::plugins::dynamixel {

SerialWorker::SerialWorker(std::shared_ptr<DxlBus> bus) : state_(std::make_shared<State>()) {
  state_->bus = std::move(bus);
  thread_ = std::thread(loop, state_);
}

SerialWorker::~SerialWorker() {
  std::unique_lock lock(state_->mutex);
  state_->stopping = true;
  for (auto& queued : state_->queue) queued.ticket->finished = true;  // Dropped
  state_->queue.clear();
  state_->bus->link().interrupt();  // a poll waiting for a reply ends now
  state_->changed.notify_all();
  const bool exited = state_->changed.wait_for(lock, std::chrono::seconds(1), [&] { return state_->exited; });
  lock.unlock();
  if (exited) thread_.join();
  else thread_.detach();  // stuck in a write; it owns a reference to the state and the bus
}

void SerialWorker::loop(std::shared_ptr<State> state) {
  std::unique_lock lock(state->mutex);
  for (;;) {
    const auto idle_ready = [&] { return state->idle && std::chrono::steady_clock::now() >= state->idle_due; };
    if (state->idle) state->changed.wait_until(lock, state->idle_due, [&] { return state->stopping || !state->queue.empty(); });
    else state->changed.wait(lock, [&] { return state->stopping || !state->queue.empty() || state->idle; });
    if (state->stopping) break;
    Job job;
    std::shared_ptr<Ticket> ticket;
    if (!state->queue.empty()) {
      Queued next = std::move(state->queue.front());
      state->queue.pop_front();
      // The interrupt raised for this job is spent; raised while the mutex is held, so it cannot be lost.
      if (next.urgent) state->bus->link().clear_interrupt();
      job = std::move(next.job);
      ticket = std::move(next.ticket);
    } else if (idle_ready()) {
      job = state->idle;
      state->idle_due = std::chrono::steady_clock::now() + state->idle_period;
    } else {
      continue;
    }
    lock.unlock();
    Outcome outcome = Outcome::Done;
    std::exception_ptr error;
    try {
      job(*state->bus);
    } catch (const Interrupted&) {
      outcome = Outcome::Dropped;  // a halt superseded it
    } catch (...) {
      outcome = Outcome::Failed;
      error = std::current_exception();
    }
    lock.lock();
    if (ticket) {
      ticket->finished = true;
      ticket->outcome = outcome;
      ticket->error = error;
      state->changed.notify_all();
    }
  }
  state->exited = true;
  state->changed.notify_all();
}

SerialWorker::Result SerialWorker::submit(Job job, std::chrono::microseconds deadline, bool urgent) {
  auto ticket = std::make_shared<Ticket>();
  std::unique_lock lock(state_->mutex);
  if (state_->stopping) return {Outcome::Dropped, nullptr};
  if (urgent) {
    for (auto& queued : state_->queue) queued.ticket->finished = true;  // Dropped
    state_->queue.clear();
    state_->queue.push_front({std::move(job), ticket, true});
    state_->bus->link().interrupt();
  } else {
    state_->queue.push_back({std::move(job), ticket, false});
  }
  state_->changed.notify_all();
  if (!state_->changed.wait_for(lock, deadline, [&] { return ticket->finished; })) return {Outcome::TimedOut, nullptr};
  return {ticket->outcome, ticket->error};
}

SerialWorker::Result SerialWorker::run(Job job, std::chrono::microseconds deadline) {
  return submit(std::move(job), deadline, false);
}

SerialWorker::Result SerialWorker::urgent(Job job, std::chrono::microseconds deadline) {
  return submit(std::move(job), deadline, true);
}

void SerialWorker::set_idle_task(Job task, std::chrono::microseconds period) {
  std::lock_guard lock(state_->mutex);
  state_->idle = std::move(task);
  state_->idle_period = period;
  state_->idle_due = std::chrono::steady_clock::now() + period;
  state_->changed.notify_all();
}

}  // namespace rcand::plugins::dynamixel
