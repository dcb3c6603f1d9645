// One thread that owns the I2C bus. Callers hand it a transaction and wait for it only up to their deadline: on a
// wedged bus the transfer stays stuck in the kernel, on this thread, while halt() returns on time and relies on the
// /OE pin. The thread and the bus live in shared state, so a worker stuck at shutdown is left behind safely.
#pragma once

#include <chrono>
#include <condition_variable>
#include <deque>
#include <exception>
#include <functional>
#include <memory>
#include <mutex>
#include <thread>

#include "i2c_bus.hpp"

namespace rcand::plugins::pca9685 {

class BusWorker {
 public:
  using Job = std::function<void(I2cBus&)>;
  enum class Outcome { Done, Failed, TimedOut, Dropped };
  struct Result {
    Outcome outcome;
    std::exception_ptr error;  // Failed: what the job threw
  };

  explicit BusWorker(std::shared_ptr<I2cBus> bus);
  // Waits up to 1 s for a job in progress, then leaves the thread behind (detached) rather than hang shutdown.
  ~BusWorker();
  BusWorker(const BusWorker&) = delete;
  BusWorker& operator=(const BusWorker&) = delete;

  // Queues `job` last and waits up to `deadline` for it. TimedOut: it still runs later (or is dropped by urgent()).
  Result run(Job job, std::chrono::microseconds deadline);
  // Drops every queued job (their waiters get Dropped), queues `job` first and waits up to `deadline` for it. For
  // halt: a command queued before the stop must never reach the motors after it.
  Result urgent(Job job, std::chrono::microseconds deadline);

 private:
  struct Ticket {
    bool finished = false;
    Outcome outcome = Outcome::Dropped;
    std::exception_ptr error;
  };
  struct Queued {
    Job job;
    std::shared_ptr<Ticket> ticket;
  };
  struct State {
    std::shared_ptr<I2cBus> bus;
    std::mutex mutex;
    std::condition_variable changed;
    std::deque<Queued> queue;
    bool stopping = false;
    bool exited = false;
  };
  static void loop(std::shared_ptr<State> state);
  Result submit(Job job, std::chrono::microseconds deadline, bool first);

  std::shared_ptr<State> state_;
  std::thread thread_;
};

}  // namespace rcand::plugins::pca9685
