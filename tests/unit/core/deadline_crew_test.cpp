// The stop path's crew: parallel calls, a deadline, and containment of a call that throws out of noexcept.
#include <doctest/doctest.h>

#include <sched.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <set>
#include <stdexcept>
#include <thread>
#include <vector>

#include "kernel/safety/estop.hpp"
#include "libs/base/deadline_crew.hpp"
#include "libs/base/steady_clock.hpp"

using namespace rcand;
using namespace rcand::kernel;
using namespace std::chrono_literals;

namespace {

// A gate the test opens: a job blocked on it is "hung" until then.
struct Gate {
  std::mutex mutex;
  std::condition_variable cv;
  bool open = false;
  void wait() {
    std::unique_lock lock(mutex);
    cv.wait(lock, [&] { return open; });
  }
  void release() {
    {
      std::lock_guard lock(mutex);
      open = true;
    }
    cv.notify_all();
  }
};

[[noreturn]] void fail_hard() { throw std::runtime_error("bus fault during halt"); }
void throws_out_of_noexcept() noexcept { fail_hard(); }

// Waits until `threads` threads named "<role>.*" sleep (in the crew: waiting for a round). A member's thread that is
// not yet waiting when its round is asked makes the call itself, so tests about which thread makes a call wait first.
void wait_until_asleep(const std::string& role, int threads) {
  for (const auto until = std::chrono::steady_clock::now() + 10s; std::chrono::steady_clock::now() < until;) {
    int asleep = 0;
    for (const auto& task : std::filesystem::directory_iterator("/proc/self/task")) {
      std::ifstream comm(task.path() / "comm"), stat(task.path() / "stat");
      std::string name, line;
      std::getline(comm, name);
      std::getline(stat, line);
      const auto state = line.rfind(") ");  // the state follows the parenthesised name
      if (name.rfind(role + ".", 0) == 0 && state != std::string::npos && line.substr(state + 2, 1) == "S") ++asleep;
    }
    if (asleep >= threads) return;
    std::this_thread::sleep_for(1ms);
  }
  FAIL("the crew's threads never all waited");
}

auto soon(std::chrono::milliseconds d) { return std::chrono::steady_clock::now() + d; }

}  // namespace

TEST_CASE("a hung job delays neither the others nor the caller beyond the deadline, and finishes in a later round") {
  Gate gate;
  std::atomic<int> quick{0};
  DeadlineCrew crew("test", {{"hung", [&] { gate.wait(); }}, {"quick", [&] { ++quick; }}});
  const auto start = std::chrono::steady_clock::now();
  auto outcomes = crew.run_all(soon(100ms));
  const auto took = std::chrono::steady_clock::now() - start;
  CHECK(took >= 90ms);
  CHECK(took < 2s);
  REQUIRE(outcomes.size() == 2);
  CHECK(outcomes[0].name == "hung");
  CHECK(outcomes[0].state == DeadlineCrew::State::Pending);
  CHECK(outcomes[1].state == DeadlineCrew::State::Done);
  CHECK(quick == 1);
  CHECK_FALSE(crew.quiesce(10ms));
  gate.release();
  CHECK(crew.quiesce(5s));
  outcomes = crew.run_all(soon(5s));  // the released job runs again for this round and finishes
  CHECK(outcomes[0].state == DeadlineCrew::State::Done);
  CHECK(quick == 2);
}

TEST_CASE("jobs the leader has not claimed run on their own threads: two jobs that each wait for the other both finish") {
  std::atomic<int> arrived{0};
  auto meet = [&] {
    ++arrived;
    const auto until = soon(2s);
    while (arrived < 2 && std::chrono::steady_clock::now() < until) std::this_thread::yield();
  };
  DeadlineCrew crew("test", {{"a", meet}, {"b", meet}});
  const auto outcomes = crew.run_all(soon(5s));
  CHECK(outcomes[0].state == DeadlineCrew::State::Done);
  CHECK(outcomes[1].state == DeadlineCrew::State::Done);
  CHECK(outcomes[0].latency_us < 1'000'000);  // they met: neither waited for the 2 s bound
}

TEST_CASE("a job that throws out of a noexcept function is reported failed and retired; the process lives on") {
  std::atomic<int> healthy{0};
  DeadlineCrew crew("test", {{"throws", [] { throws_out_of_noexcept(); }}, {"healthy", [&] { ++healthy; }}});
  auto outcomes = crew.run_all(soon(5s));
  CHECK(outcomes[0].state == DeadlineCrew::State::Failed);
  CHECK(outcomes[0].error == "bus fault during halt");
  CHECK(outcomes[1].state == DeadlineCrew::State::Done);
  const auto start = std::chrono::steady_clock::now();
  outcomes = crew.run_all(soon(5s));  // retired: reported at once, not waited for
  CHECK(std::chrono::steady_clock::now() - start < 1s);
  CHECK(outcomes[0].state == DeadlineCrew::State::Failed);
  CHECK(healthy == 2);
}

TEST_CASE("a round wakes only the leader, which makes the calls one after another on one thread, pinned to one CPU") {
  std::mutex mutex;
  std::vector<std::pair<std::string, std::thread::id>> calls;
  std::vector<int> allowed_cpus;  // the leader is pinned to its caller's CPU: one allowed CPU
  const auto record = [&](std::string name) {
    return [&, name] {
      cpu_set_t set;
      CPU_ZERO(&set);
      const int cpus = sched_getaffinity(0, sizeof set, &set) == 0 ? CPU_COUNT(&set) : -1;
      std::lock_guard lock(mutex);
      calls.emplace_back(name, std::this_thread::get_id());
      allowed_cpus.push_back(cpus);
    };
  };
  // A hand-off of an hour: only the leader can have made these calls within the round.
  DeadlineCrew crew("inturn", {{"a", record("a")}, {"b", record("b")}, {"c", record("c")}}, {}, 1h);
  wait_until_asleep("inturn", 4);
  for (int round = 1; round <= 3; ++round) {
    const auto outcomes = crew.run_all(soon(10s));
    for (const auto& outcome : outcomes) CHECK(outcome.state == DeadlineCrew::State::Done);
  }
  REQUIRE(calls.size() == 9);
  CHECK(calls[0].first == "a");  // in the crew's order (a later round may start with the call the leader holds)
  CHECK(calls[1].first == "b");
  CHECK(calls[2].first == "c");
  for (std::size_t round = 0; round < 3; ++round) {
    std::set<std::string> names;
    for (std::size_t i = round * 3; i < round * 3 + 3; ++i) names.insert(calls[i].first);
    CHECK(names == std::set<std::string>{"a", "b", "c"});
  }
  for (std::size_t i = 0; i < calls.size(); ++i) {
    CHECK(calls[i].second == calls[0].second);
    CHECK(allowed_cpus[i] == 1);
  }
}

TEST_CASE("a call that hangs on the leader: the others wait for the hand-off at most, and later rounds skip the leader") {
  Gate gate;
  std::mutex mutex;
  std::condition_variable called;
  int quick = 0;
  DeadlineCrew crew("test",
                    {{"hung", [&] { gate.wait(); }},
                     {"quick",
                      [&] {
                        std::lock_guard lock(mutex);
                        ++quick;
                        called.notify_all();
                      }}},
                    {}, 1h);
  const auto quick_calls = [&] {
    std::lock_guard lock(mutex);
    return quick;
  };
  auto outcomes = crew.run_all(soon(100ms));
  CHECK(outcomes[0].state == DeadlineCrew::State::Pending);
  // "quick" was not the leader's to make (it is inside "hung"): its own thread was woken at the round's end at the
  // latest (a round is never left with calls nobody makes).
  {
    std::unique_lock lock(mutex);
    CHECK(called.wait_for(lock, 10s, [&] { return quick >= 1; }));
  }
  CHECK(quick_calls() == 1);
  // The leader is still inside "hung": the next round wakes the members' own threads at once, not after an hour.
  outcomes = crew.run_all(soon(1s));
  CHECK(outcomes[1].state == DeadlineCrew::State::Done);
  CHECK(quick_calls() == 2);
  gate.release();
  CHECK(crew.quiesce(5s));
  outcomes = crew.run_all(soon(10s));  // the leader is back: it makes both calls
  CHECK(outcomes[0].state == DeadlineCrew::State::Done);
  CHECK(outcomes[1].state == DeadlineCrew::State::Done);
}

TEST_CASE("a throw on the leader retires that job and parks the leader; later rounds run on the members' threads") {
  std::atomic<std::thread::id> healthy_thread;
  std::atomic<int> healthy{0};
  DeadlineCrew crew("thrower",
                    {{"healthy",
                      [&] {
                        healthy_thread = std::this_thread::get_id();
                        ++healthy;
                      }},
                     {"throws", [] { throws_out_of_noexcept(); }}},
                    {}, 1h);
  wait_until_asleep("thrower", 3);
  auto outcomes = crew.run_all(soon(10s));  // the leader runs "healthy", then "throws", and parks
  CHECK(outcomes[0].state == DeadlineCrew::State::Done);
  CHECK(outcomes[1].state == DeadlineCrew::State::Failed);
  CHECK(outcomes[1].error == "bus fault during halt");
  const auto leader = healthy_thread.load();
  outcomes = crew.run_all(soon(10s));  // well before the hour's hand-off: "healthy"'s own thread was woken at once
  CHECK(outcomes[0].state == DeadlineCrew::State::Done);
  CHECK(outcomes[1].state == DeadlineCrew::State::Failed);
  CHECK(healthy == 2);
  CHECK(healthy_thread.load() != leader);
}

namespace {
class HungDrive final : public rcand::sdk::DifferentialDrive {
 public:
  explicit HungDrive(Gate& gate) : gate_(gate) {}
  void set_wheel_speeds(double, double) override {}
  void halt() noexcept override { gate_.wait(); }

 private:
  Gate& gate_;
};
class CountingDrive final : public rcand::sdk::DifferentialDrive {
 public:
  void set_wheel_speeds(double, double) override {}
  void halt() noexcept override { ++halts; }
  std::atomic<int> halts{0};
};
}  // namespace

TEST_CASE("the e-stop latches and halts the healthy driver at once while another driver's halt() hangs") {
  SteadyClock clock;
  ActuatorTable table;
  Estop estop(clock, table);
  Gate gate;
  HungDrive hung(gate);
  CountingDrive good;
  InstanceHealth hung_health, good_health;
  table.add("hung0", "differential_drive", "org.test", &hung, &hung_health);
  table.add("good0", "differential_drive", "org.test", &good, &good_health);
  DeadlineCrew crew("halt", {{"hung0", [&] { hung.halt(); }}, {"good0", [&] { good.halt(); }}});
  estop.use_halt_crew(&crew);

  const auto start = std::chrono::steady_clock::now();
  const auto report = estop.latch("test", "unit");
  CHECK(std::chrono::steady_clock::now() - start < Estop::kHaltDeadline + 400ms);
  CHECK(estop.latched());
  REQUIRE(report.drivers.size() == 2);
  CHECK(report.drivers[0].state == "halt_pending");
  CHECK_FALSE(report.drivers[0].halted);
  CHECK(report.drivers[1].state == "halted");
  CHECK(good.halts == 1);
  gate.release();
  CHECK(crew.quiesce(5s));
  estop.use_halt_crew(nullptr);
}

TEST_CASE("start_all returns before a hung job, and the watcher reports the round off the caller's path") {
  Gate gate;
  std::atomic<int> quick{0};
  std::mutex mutex;
  std::condition_variable reported;
  std::vector<std::vector<DeadlineCrew::Outcome>> reports;
  DeadlineCrew crew("watched",
                    {{"hung", [&] { gate.wait(); }}, {"quick", [&] { ++quick; }}, {"throws", [] { throws_out_of_noexcept(); }}});
  crew.watch(50ms, [&](std::vector<DeadlineCrew::Outcome> outcomes) {
    std::lock_guard lock(mutex);
    reports.push_back(std::move(outcomes));
    reported.notify_all();
  });
  crew.start_all();  // returns at once: the hung job is the watcher's to wait for (up to 50 ms), never the caller's
  {
    std::unique_lock lock(mutex);
    REQUIRE(reported.wait_for(lock, 10s, [&] { return !reports.empty(); }));
    REQUIRE(reports[0].size() == 3);
    CHECK(reports[0][0].name == "hung");
    CHECK(reports[0][0].state == DeadlineCrew::State::Pending);
    CHECK(reports[0][1].state == DeadlineCrew::State::Done);
    CHECK(reports[0][2].state == DeadlineCrew::State::Failed);
    CHECK(reports[0][2].error.find("bus fault during halt") != std::string::npos);
  }
  CHECK(quick == 1);
  gate.release();
  crew.start_all();  // the next round: every job that can still run runs again, the one that threw stays retired
  std::unique_lock lock(mutex);
  REQUIRE(reported.wait_for(lock, 10s, [&] { return reports.size() >= 2; }));
  CHECK(reports[1][0].state == DeadlineCrew::State::Done);
  CHECK(reports[1][1].state == DeadlineCrew::State::Done);
  CHECK(reports[1][2].state == DeadlineCrew::State::Failed);
  CHECK(quick == 2);
}

// A plugin reload latches the e-stop (start_all: the watcher owes a round of on_estop() calls), then quiesces the old
// crew and unloads the plugin. quiesce() must count the round the watcher has not started yet: seen quiet before the
// watcher woke, the reload unloaded the code its on_estop() then ran in (rcand died in the reload test).
TEST_CASE("quiesce right after start_all waits for the round the watcher still owes") {
  for (int attempt = 0; attempt < 50; ++attempt) {
    std::atomic<int> calls{0};
    DeadlineCrew crew("owed", {{"slow", [&] {
                                  std::this_thread::sleep_for(2ms);
                                  ++calls;
                                }}});
    crew.watch(1s, [](std::vector<DeadlineCrew::Outcome>) {});
    crew.start_all();
    REQUIRE(crew.quiesce(5s));
    REQUIRE(calls == 1);  // the owed round ran to its end before quiesce said quiet
  }
}
