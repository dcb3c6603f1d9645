// One thread that owns the Dynamixel bus (the pca9685 bus worker's design, plus two things a serial bus needs).
// Callers hand it a transaction and wait only up to their deadline. urgent() (halt) drops every queued job, cuts
// the wait of the transaction in progress short through SerialLink::interrupt(), and runs first, so halt waits at
// most for the packet being written. Between jobs the worker runs an idle task at a fixed period (the status poll,
// which is also the Bus Watchdog's keep-alive). The thread and the bus live in shared state, so a worker stuck in
// a write to a stalled adapter at shutdown is left behind safely.
#pragma once

#include <chrono>
#include <condition_variable>
#include <deque>
#include <exception>
#include <functional>
#include <memory>
#include <mutex>
#include <thread>

#include "dxl_bus.hpp"

namespace rcand::plugins::dynamixel {

class SerialWorker {
 public:
  using Job = std::function<void(DxlBus&)>;
  enum class Outcome { Done, Failed, TimedOut, Dropped };
  struct Result {
    Outcome outcome;
    std::exception_ptr error;  // Failed: what the job threw
  };

  explicit SerialWorker(std::shared_ptr<DxlBus> bus);
  // Waits up to 1 s for a job in progress, then leaves the thread behind (detached) rather than hang shutdown.
  ~SerialWorker();
  SerialWorker(const SerialWorker&) = delete;
  SerialWorker& operator=(const SerialWorker&) = delete;

  // Queues `job` last and waits up to `deadline` for it. TimedOut: it still runs later (or is dropped by urgent()).
  Result run(Job job, std::chrono::microseconds deadline);
  // Drops every queued job (their waiters get Dropped), interrupts the one in progress (its waiter gets Dropped
  // too), runs `job` next and waits up to `deadline` for it.
  Result urgent(Job job, std::chrono::microseconds deadline);
  // Runs `task` whenever the queue is empty and `period` has passed since it last started. Interrupted like a job.
  void set_idle_task(Job task, std::chrono::microseconds period);

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
    std::shared_ptr<DxlBus> bus;
    std::mutex mutex;
    std::condition_variable changed;
    std::deque<Queued> queue;
    Job idle;
    std::chrono::microseconds idle_period{0};
    std::chrono::steady_clock::time_point idle_due{};
    bool stopping = false;
    bool exited = false;
  };
  static void loop(std::shared_ptr<State> state);
  Result submit(Job job, std::chrono::microseconds deadline, bool urgent);

  std::shared_ptr<State> state_;
  std::thread thread_;
};

}  // namespace rcand::plugins::dynamixel
