// One thread that owns a hardware bus (I2C, a serial line, SPI, CAN): the pattern a driver needs so that halt() returns
// by its deadline even when the bus hangs. Header-only: no ABI of its own.
//
// - Callers hand the worker a job (a function of the bus) and wait only up to their deadline. A transfer stuck in the
//   kernel stays stuck on the worker's thread; the caller gets TimedOut and the job still runs later.
// - urgent() (for halt) drops every queued job, their waiters get Dropped, and runs first: a command queued before
//   the stop never reaches the hardware after it.
// - An interruptible bus (InterruptibleBus below) also has the job in progress cut short by urgent(): halt waits at
//   most for the transfer that cannot be interrupted (a packet being written), not for a read waiting for a late reply.
// - An optional idle task runs whenever the queue is empty and its period has passed (a status poll, which can double
//   as the hardware's watchdog keep-alive). It is interrupted like a job.
// - The thread and the bus live in shared state: the destructor waits up to 1 s for the job in progress, then leaves
//   the thread behind (detached) rather than hang shutdown; the thread keeps the bus alive until the transfer returns.
//   Jobs must therefore capture nothing the driver destroys after the worker (or share it by shared_ptr).
//
//   rcand::sdk::BusWorker<I2cBus> worker(bus);
//   const auto result = worker.urgent([block](I2cBus& bus) { bus.write(kAddress, block); }, 5ms);
//   if (result.outcome == rcand::sdk::BusOutcome::TimedOut) oe_pin.disable();  // the bus is wedged: the fail-safe
//
// plugins/pca9685 (I2C) and plugins/dynamixel (an interruptible serial bus with a status poll) use it.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <deque>
#include <exception>
#include <functional>
#include <memory>
#include <mutex>
#include <thread>
#include <utility>

namespace rcand::sdk {

// A bus whose transfer in progress another thread can cut short. interrupt(): any thread, never throws; the transfer
// in progress (or the next one) throws Bus::Interrupted until clear_interrupt(). The worker raises it for urgent() and
// its destructor, and clears it on its own thread just before the urgent job starts.
template <class Bus>
concept InterruptibleBus = requires(Bus& bus) {
  typename Bus::Interrupted;
  requires noexcept(bus.interrupt());
  requires noexcept(bus.clear_interrupt());
};

enum class BusOutcome {
  Done,
  Failed,    // the job threw: Result::error holds what
  TimedOut,  // the caller's deadline passed; the job still runs later (or is dropped by urgent())
  Dropped,   // never ran (urgent() or the destructor dropped it), or an interrupt cut it short
};

template <class Bus> class BusWorker {
 public:
  using Job = std::function<void(Bus&)>;
  using Outcome = BusOutcome;
  struct Result {
    Outcome outcome;
    std::exception_ptr error;  // Failed: what the job threw
  };

  explicit BusWorker(std::shared_ptr<Bus> bus) : state_(std::make_shared<State>()) {
    state_->bus = std::move(bus);
    thread_ = std::thread(loop, state_);
  }
  // Waits up to 1 s for a job in progress, then leaves the thread behind (detached) rather than hang shutdown.
  ~BusWorker() {
    std::unique_lock lock(state_->mutex);
    state_->stopping = true;
    drop_queued(*state_);
    if constexpr (InterruptibleBus<Bus>) state_->bus->interrupt();  // a read waiting for a reply ends now
    state_->changed.notify_all();
    const bool exited = state_->changed.wait_for(lock, std::chrono::seconds(1), [&] { return state_->exited; });
    lock.unlock();
    if (exited) thread_.join();
    else thread_.detach();  // stuck in a transfer; it owns a reference to the state and the bus
  }
  BusWorker(const BusWorker&) = delete;
  BusWorker& operator=(const BusWorker&) = delete;

  // Queues `job` last and waits up to `deadline` for it. TimedOut: it still runs later (or is dropped by urgent()).
  Result run(Job job, std::chrono::microseconds deadline) { return submit(std::move(job), deadline, false); }
  // Drops every queued job (their waiters get Dropped), interrupts the one in progress on an InterruptibleBus (its
  // waiter gets Dropped too), runs `job` next and waits up to `deadline` for it. For halt: a command queued before
  // the stop must never reach the hardware after it.
  Result urgent(Job job, std::chrono::microseconds deadline) { return submit(std::move(job), deadline, true); }
  // Runs `task` whenever the queue is empty and `period` has passed since it last started (first: `period` from now).
  // Its outcome goes nowhere: the task reports its own errors.
  void set_idle_task(Job task, std::chrono::microseconds period) {
    std::lock_guard lock(state_->mutex);
    state_->idle = std::move(task);
    state_->idle_period = period;
    state_->idle_due = std::chrono::steady_clock::now() + period;
    state_->changed.notify_all();
  }
  // Jobs waiting to start, not counting the one in progress: the backlog, for a driver's status.
  std::size_t queued() const {
    std::lock_guard lock(state_->mutex);
    return state_->queue.size();
  }

 private:
  struct Ticket {
    bool finished = false;
    Outcome outcome = Outcome::Dropped;
    std::exception_ptr error;
  };
  struct Queued {
    Job job;
    std::shared_ptr<Ticket> ticket;
    bool urgent = false;
  };
  struct State {
    std::shared_ptr<Bus> bus;
    std::mutex mutex;
    std::condition_variable changed;
    std::deque<Queued> queue;
    Job idle;
    std::chrono::microseconds idle_period{0};
    std::chrono::steady_clock::time_point idle_due{};
    bool stopping = false;
    bool exited = false;
  };

  // With the mutex held: every queued job's waiter gets Dropped.
  static void drop_queued(State& state) {
    for (auto& queued : state.queue) queued.ticket->finished = true;
    state.queue.clear();
  }

  static Outcome execute(const Job& job, Bus& bus, std::exception_ptr& error) {
    try {
      if constexpr (InterruptibleBus<Bus>) {
        try {
          job(bus);
        } catch (const typename Bus::Interrupted&) {
          return Outcome::Dropped;  // an urgent job superseded it
        }
      } else {
        job(bus);
      }
      return Outcome::Done;
    } catch (...) {
      error = std::current_exception();
      return Outcome::Failed;
    }
  }

  static void loop(std::shared_ptr<State> state) {
    std::unique_lock lock(state->mutex);
    for (;;) {
      if (state->idle) state->changed.wait_until(lock, state->idle_due, [&] { return state->stopping || !state->queue.empty(); });
      else state->changed.wait(lock, [&] { return state->stopping || !state->queue.empty() || state->idle; });
      if (state->stopping) break;
      Job job;
      std::shared_ptr<Ticket> ticket;
      if (!state->queue.empty()) {
        Queued next = std::move(state->queue.front());
        state->queue.pop_front();
        // The interrupt raised for this job is spent; raised while the mutex is held, so it cannot be lost.
        if constexpr (InterruptibleBus<Bus>)
          if (next.urgent) state->bus->clear_interrupt();
        job = std::move(next.job);
        ticket = std::move(next.ticket);
      } else if (state->idle && std::chrono::steady_clock::now() >= state->idle_due) {
        job = state->idle;
        state->idle_due = std::chrono::steady_clock::now() + state->idle_period;
      } else {
        continue;  // woken early (idle task just set) or spuriously
      }
      lock.unlock();
      std::exception_ptr error;
      const Outcome outcome = execute(job, *state->bus, error);
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

  Result submit(Job job, std::chrono::microseconds deadline, bool urgent) {
    auto ticket = std::make_shared<Ticket>();
    std::unique_lock lock(state_->mutex);
    if (state_->stopping) return {Outcome::Dropped, nullptr};
    if (urgent) {
      drop_queued(*state_);
      state_->queue.push_front({std::move(job), ticket, true});
      if constexpr (InterruptibleBus<Bus>) state_->bus->interrupt();
    } else {
      state_->queue.push_back({std::move(job), ticket, false});
    }
    state_->changed.notify_all();
    if (!state_->changed.wait_for(lock, deadline, [&] { return ticket->finished; })) return {Outcome::TimedOut, nullptr};
    return {ticket->outcome, ticket->error};
  }

  std::shared_ptr<State> state_;
  std::thread thread_;
};

}  // namespace rcand::sdk
