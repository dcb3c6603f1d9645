// rcand/sdk/bus_worker.hpp, the one thread that owns a hardware bus (the pca9685 and dynamixel drivers use it):
// deadlines, urgent() dropping the queue and interrupting the job in progress, the idle task, exceptions, and a
// destructor that leaves a stuck transfer behind. Jobs block on events the test releases, never on luck.
#include <rcand/sdk/bus_worker.hpp>  // first: the header compiles on its own

#include <doctest/doctest.h>

#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

using rcand::sdk::BusOutcome;
using rcand::sdk::BusWorker;
using namespace std::chrono_literals;

namespace {

// A one-shot flag to wait on. wait() is bounded so a broken worker fails the test instead of hanging it.
class Event {
 public:
  void set() {
    {
      std::lock_guard lock(mutex_);
      set_ = true;
    }
    changed_.notify_all();
  }
  bool is_set() const {
    std::lock_guard lock(mutex_);
    return set_;
  }
  bool wait(std::chrono::milliseconds limit = 10s) {
    std::unique_lock lock(mutex_);
    return changed_.wait_for(lock, limit, [&] { return set_; });
  }

 private:
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  bool set_ = false;
};

// What ran, in order (written by the worker, read by the test).
class Journal {
 public:
  void note(std::string what) {
    std::lock_guard lock(mutex_);
    entries_.push_back(std::move(what));
  }
  std::vector<std::string> entries() const {
    std::lock_guard lock(mutex_);
    return entries_;
  }

 private:
  mutable std::mutex mutex_;
  std::vector<std::string> entries_;
};

// A bus with no way to cut a transfer short (I2C through the kernel).
struct PlainBus {};

// A bus whose reads another thread can interrupt (a serial line): the InterruptibleBus contract.
class SerialBus {
 public:
  struct Interrupted : std::runtime_error {
    Interrupted() : std::runtime_error("interrupted") {}
  };
  void interrupt() noexcept {
    {
      std::lock_guard lock(mutex_);
      raised_ = true;
      ++interrupts_;
    }
    changed_.notify_all();
  }
  void clear_interrupt() noexcept {
    std::lock_guard lock(mutex_);
    raised_ = false;
    ++clears_;
  }
  // A read whose reply never comes: it ends only by interrupt().
  void read_without_reply() {
    std::unique_lock lock(mutex_);
    if (!changed_.wait_for(lock, 10s, [&] { return raised_; })) throw std::runtime_error("never interrupted");
    throw Interrupted();
  }
  bool raised() const {
    std::lock_guard lock(mutex_);
    return raised_;
  }
  int interrupts() const {
    std::lock_guard lock(mutex_);
    return interrupts_;
  }
  int clears() const {
    std::lock_guard lock(mutex_);
    return clears_;
  }

 private:
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  bool raised_ = false;
  int interrupts_ = 0, clears_ = 0;
};

static_assert(rcand::sdk::InterruptibleBus<SerialBus>);
static_assert(!rcand::sdk::InterruptibleBus<PlainBus>);

// The queue has no event of its own: wait (bounded) until a waiter on another thread has queued its job.
template <class Bus> bool wait_queued(const BusWorker<Bus>& worker, std::size_t count) {
  const auto give_up = std::chrono::steady_clock::now() + 10s;
  while (worker.queued() != count) {
    if (std::chrono::steady_clock::now() > give_up) return false;
    std::this_thread::yield();
  }
  return true;
}

}  // namespace

TEST_CASE("bus worker: a job past its caller's deadline is TimedOut and still runs later") {
  Event release, ran;
  BusWorker<PlainBus> worker(std::make_shared<PlainBus>());
  const auto late = worker.run(
      [&](PlainBus&) {
        release.wait();
        ran.set();
      },
      1ms);
  CHECK(late.outcome == BusOutcome::TimedOut);
  CHECK(late.error == nullptr);
  CHECK_FALSE(ran.is_set());
  release.set();
  CHECK(ran.wait());
  CHECK(worker.run([](PlainBus&) {}, 10s).outcome == BusOutcome::Done);
}

TEST_CASE("bus worker: urgent() drops every queued job (their waiters get Dropped) and runs next") {
  Event started, release;
  Journal journal;
  BusWorker<PlainBus> worker(std::make_shared<PlainBus>());
  std::optional<BusWorker<PlainBus>::Result> in_progress, queued, halt;
  std::thread first([&] {
    in_progress = worker.run(
        [&](PlainBus&) {
          started.set();
          release.wait();
          journal.note("in progress");
        },
        10s);
  });
  REQUIRE(started.wait());
  std::thread second([&] { queued = worker.run([&](PlainBus&) { journal.note("queued"); }, 10s); });
  REQUIRE(wait_queued(worker, 1));
  CHECK(worker.run([&](PlainBus&) { journal.note("queued, its caller gone"); }, 0us).outcome == BusOutcome::TimedOut);
  CHECK(worker.queued() == 2);

  // A plain bus cannot be interrupted: the urgent job waits for the one in progress, from its own thread.
  std::thread stopper([&] { halt = worker.urgent([&](PlainBus&) { journal.note("urgent"); }, 10s); });
  second.join();  // returns once urgent() dropped its job
  REQUIRE(queued.has_value());
  CHECK(queued->outcome == BusOutcome::Dropped);
  CHECK(worker.queued() == 1);  // the urgent job, behind the one in progress
  release.set();
  stopper.join();
  first.join();
  REQUIRE(halt.has_value());
  CHECK(halt->outcome == BusOutcome::Done);
  REQUIRE(in_progress.has_value());
  CHECK(in_progress->outcome == BusOutcome::Done);

  CHECK(worker.run([&](PlainBus&) { journal.note("after"); }, 10s).outcome == BusOutcome::Done);
  CHECK(journal.entries() == std::vector<std::string>{"in progress", "urgent", "after"});
}

TEST_CASE("bus worker: urgent() interrupts the job in progress on an interruptible bus; its waiter gets Dropped") {
  auto bus = std::make_shared<SerialBus>();
  Event started;
  BusWorker<SerialBus> worker(bus);
  std::optional<BusWorker<SerialBus>::Result> polled;
  std::thread poller([&] {
    polled = worker.run(
        [&](SerialBus& serial) {
          started.set();
          serial.read_without_reply();
        },
        10s);
  });
  REQUIRE(started.wait());
  bool raised_during_halt = true;
  const auto halt = worker.urgent([&](SerialBus& serial) { raised_during_halt = serial.raised(); }, 10s);
  poller.join();
  CHECK(halt.outcome == BusOutcome::Done);
  REQUIRE(polled.has_value());
  CHECK(polled->outcome == BusOutcome::Dropped);
  CHECK(polled->error == nullptr);
  CHECK(bus->interrupts() == 1);
  CHECK(bus->clears() == 1);
  CHECK_FALSE(raised_during_halt);  // cleared before the urgent job started, so its own reads are not cut short
}

TEST_CASE("bus worker: on an interruptible bus, an exception other than Interrupted is still Failed") {
  BusWorker<SerialBus> worker(std::make_shared<SerialBus>());
  const auto result = worker.run([](SerialBus&) { throw std::runtime_error("checksum mismatch"); }, 10s);
  CHECK(result.outcome == BusOutcome::Failed);
  REQUIRE(result.error != nullptr);
  CHECK_THROWS_WITH_AS(std::rethrow_exception(result.error), "checksum mismatch", std::runtime_error);
}

TEST_CASE("bus worker: a job that throws is Failed with what it threw, and the worker carries on") {
  BusWorker<PlainBus> worker(std::make_shared<PlainBus>());
  const auto result = worker.run([](PlainBus&) { throw std::invalid_argument("no ACK at 0x40"); }, 10s);
  CHECK(result.outcome == BusOutcome::Failed);
  REQUIRE(result.error != nullptr);
  CHECK_THROWS_WITH_AS(std::rethrow_exception(result.error), "no ACK at 0x40", std::invalid_argument);
  CHECK(worker.run([](PlainBus&) {}, 10s).outcome == BusOutcome::Done);
}

TEST_CASE("bus worker: the idle task runs only when the queue is empty") {
  constexpr auto period = 5ms;
  Event started, release, idle_ran;
  Journal journal;
  BusWorker<PlainBus> worker(std::make_shared<PlainBus>());
  std::thread busy([&] {
    CHECK(worker
              .run(
                  [&](PlainBus&) {
                    started.set();
                    release.wait();
                    journal.note("job");
                  },
                  10s)
              .outcome == BusOutcome::Done);
  });
  REQUIRE(started.wait());
  worker.set_idle_task(
      [&](PlainBus&) {
        journal.note("idle");
        idle_ran.set();
      },
      period);
  const auto idle_due = std::chrono::steady_clock::now() + period;
  CHECK(worker.run([&](PlainBus&) { journal.note("queued"); }, 0us).outcome == BusOutcome::TimedOut);
  std::this_thread::sleep_until(idle_due);  // time passing is the point here: the idle task is overdue
  release.set();
  busy.join();
  REQUIRE(idle_ran.wait());
  const auto entries = journal.entries();
  REQUIRE(entries.size() >= 3);
  CHECK(entries[0] == "job");
  CHECK(entries[1] == "queued");
  CHECK(entries[2] == "idle");
}

TEST_CASE("bus worker: the idle task's n-th run starts no sooner than n periods after it was set") {
  constexpr auto period = 10ms;
  constexpr std::size_t runs = 4;
  std::mutex mutex;
  std::vector<std::chrono::steady_clock::time_point> starts;
  Event enough;
  BusWorker<PlainBus> worker(std::make_shared<PlainBus>());
  const auto set_at = std::chrono::steady_clock::now();
  worker.set_idle_task(
      [&](PlainBus&) {
        std::lock_guard lock(mutex);
        starts.push_back(std::chrono::steady_clock::now());
        if (starts.size() == runs) enough.set();
        if (starts.size() == 2) throw std::runtime_error("a poll that fails");  // goes nowhere; the next still runs
      },
      period);
  REQUIRE(enough.wait());
  std::lock_guard lock(mutex);
  // Each run is due a period after the previous one was picked, and picked before it notes its start.
  for (std::size_t i = 0; i < starts.size(); ++i) CHECK(starts[i] - set_at >= period * static_cast<int>(i + 1));
}

TEST_CASE("bus worker: the destructor leaves a job stuck in a transfer behind after 1 s, the bus kept alive") {
  // Everything the stuck job touches is shared with it: it outlives the worker and this scope's locals.
  auto started = std::make_shared<Event>(), release = std::make_shared<Event>(), finished = std::make_shared<Event>();
  auto bus = std::make_shared<PlainBus>();
  const std::weak_ptr<PlainBus> watch = bus;
  auto worker = std::make_unique<BusWorker<PlainBus>>(std::move(bus));
  CHECK(worker
            ->run(
                [started, release, finished](PlainBus&) {
                  started->set();
                  release->wait(30s);
                  finished->set();
                },
                0us)
            .outcome == BusOutcome::TimedOut);
  REQUIRE(started->wait());
  const auto begin = std::chrono::steady_clock::now();
  worker.reset();
  const auto took = std::chrono::steady_clock::now() - begin;
  CHECK(took >= 1s);
  CHECK(took < 5s);  // 1 s and a generous margin for a loaded machine
  CHECK_FALSE(finished->is_set());
  CHECK_FALSE(watch.expired());  // the left-behind thread still owns the bus
  release->set();
  CHECK(finished->wait());
}

TEST_CASE("bus worker: the destructor interrupts a read waiting for a reply and joins the thread") {
  auto bus = std::make_shared<SerialBus>();
  Event started, ended;
  {
    BusWorker<SerialBus> worker(bus);
    CHECK(worker
              .run(
                  [&](SerialBus& serial) {
                    started.set();
                    try {
                      serial.read_without_reply();
                    } catch (...) {
                      ended.set();
                      throw;
                    }
                  },
                  0us)
              .outcome == BusOutcome::TimedOut);
    REQUIRE(started.wait());
  }
  CHECK(ended.is_set());  // joined, not left behind: the read ended before the destructor returned
  CHECK(bus->interrupts() == 1);
}
