#include "libs/base/deadline_crew.hpp"

#include <linux/futex.h>
#include <pthread.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <climits>
#include <ctime>

#include <algorithm>
#include <atomic>
#include <deque>
#include <stdexcept>
#include <thread>

#include "libs/base/terminate_trap.hpp"

namespace rcand {
namespace {

using Clock = std::chrono::steady_clock;
// The stop path spins this long before sleeping: a healthy halt() returns within microseconds, and sleeping (or
// yielding, which under load hands the core to another process for a whole time slice) would add a scheduler
// round trip to every stop. After it, the stop path sleeps on a futex until a member finishes or the deadline.
constexpr auto kSpinFor = std::chrono::microseconds(50);
constexpr std::uint32_t kStop = 0xffffffffu;

// Raw futexes: the only wait with both a timeout and no lock shared with the members.
void futex_wait(std::atomic<std::uint32_t>& word, std::uint32_t expected, const timespec* timeout) noexcept {
  syscall(SYS_futex, reinterpret_cast<std::uint32_t*>(&word), FUTEX_WAIT_PRIVATE, expected, timeout, nullptr, 0);
}
void futex_wake(std::atomic<std::uint32_t>& word, int count) noexcept {
  syscall(SYS_futex, reinterpret_cast<std::uint32_t*>(&word), FUTEX_WAKE_PRIVATE, count, nullptr, nullptr, 0);
}
// Rounds wrap around after 2^32 stops: compare by distance.
bool reached(std::uint32_t value, std::uint32_t target) noexcept { return static_cast<std::int32_t>(value - target) >= 0; }

}  // namespace

// Lock-free between the stop path and the members: one atomic per fact, so starting a round is a store and a
// futex wake per member, and the stop path never waits for a lock a member holds.
struct DeadlineCrew::Shared {
  struct Member {
    std::string name;
    std::function<void()> call;
    std::thread thread;
    std::atomic<std::uint32_t> requested{0};  // the latest round asked of it (kStop: exit)
    std::atomic<std::uint32_t> finished{0};   // the latest round it completed
    std::atomic<std::int64_t> latency_us{0};
    std::atomic<bool> busy{false};     // inside the plugin call
    std::atomic<bool> retired{false};  // the call threw out of noexcept: parked for good
    std::string failure;               // written before `retired` is set, read after it is seen
  };

  std::atomic<std::uint32_t> round{0};
  std::atomic<std::uint32_t> completions{0};  // bumped (and woken) whenever a member finishes or retires
  std::deque<Member> members;                 // deque: members never move, their threads hold references
  // watch(): counts start_all()'s requests (kStop: the watcher exits), and what the watcher does with a round.
  std::atomic<std::uint32_t> watched{0};
  std::atomic<std::uint32_t> watch_started{0};  // the latest request the watcher has turned into a round
  std::chrono::milliseconds watch_within{0};
  std::function<void(std::vector<Outcome>)> report;

  void serve(Member& member);
  void completed() noexcept {
    completions.fetch_add(1, std::memory_order_release);
    futex_wake(completions, INT_MAX);
  }
  // No member inside a call, and no request the watcher has yet to start: a crew about to be torn down (a plugin
  // reload right after a stop) must not have a round it still owes.
  bool quiet() const noexcept {
    const std::uint32_t asked = watched.load(std::memory_order_acquire);
    if (asked != kStop && watch_started.load(std::memory_order_acquire) != asked) return false;
    return std::all_of(members.begin(), members.end(), [](const Member& m) {
      return m.retired.load() || (!m.busy.load() && reached(m.finished.load(), m.requested.load()));
    });
  }
};

void DeadlineCrew::Shared::serve(Member& member) {
  TerminateTrap trap([this, &member](std::string_view what) {
    member.failure.assign(what);
    member.busy.store(false);
    member.retired.store(true, std::memory_order_release);
    completed();
  });
  std::uint32_t seen = 0;
  for (;;) {
    std::uint32_t taken = member.requested.load(std::memory_order_acquire);
    while (taken == seen) {
      futex_wait(member.requested, seen, nullptr);
      taken = member.requested.load(std::memory_order_acquire);
    }
    if (taken == kStop) return;
    seen = taken;
    member.busy.store(true);
    const auto start = Clock::now();
    member.call();
    member.latency_us.store(std::chrono::duration_cast<std::chrono::microseconds>(Clock::now() - start).count());
    member.finished.store(taken, std::memory_order_release);
    member.busy.store(false);
    completed();
  }
}

DeadlineCrew::DeadlineCrew(std::string role, std::vector<Job> jobs, std::function<void()> on_thread_start)
    : shared_(std::make_shared<Shared>()), role_(role), on_thread_start_(on_thread_start) {
  for (std::size_t i = 0; i < jobs.size(); ++i) {
    auto& member = shared_->members.emplace_back();
    member.name = std::move(jobs[i].name);
    member.call = std::move(jobs[i].call);
  }
  for (std::size_t i = 0; i < shared_->members.size(); ++i) {
    auto& member = shared_->members[i];
    const std::string thread_name = (role + "." + std::to_string(i)).substr(0, 15);
    member.thread = std::thread([shared = shared_, &member, thread_name, on_thread_start] {
      pthread_setname_np(pthread_self(), thread_name.c_str());
      if (on_thread_start) on_thread_start();
      shared->serve(member);
    });
  }
}

DeadlineCrew::~DeadlineCrew() {
  if (watcher_.joinable()) {  // it waits at most watch_within for a round, then sees kStop
    shared_->watched.store(kStop, std::memory_order_release);
    futex_wake(shared_->watched, 1);
    watcher_.join();
  }
  for (auto& member : shared_->members) {
    member.requested.store(kStop, std::memory_order_release);
    futex_wake(member.requested, 1);
    // A member inside a plugin call (or parked after a throw) may never come back: it keeps the shared state alive.
    if (member.busy.load() || member.retired.load()) member.thread.detach();
    else member.thread.join();
  }
}

// `each(f)` calls f(member) for every selected member, in the order the outcomes are reported.
template <class ForEach> std::uint32_t DeadlineCrew::start_round(ForEach each) noexcept {
  auto& s = *shared_;
  std::uint32_t round = s.round.fetch_add(1) + 1;
  if (round == kStop) round = s.round.fetch_add(1) + 1;  // kStop is the exit request, never a round
  each([&](Shared::Member& member) {
    if (member.retired.load(std::memory_order_acquire)) return;
    std::uint32_t current = member.requested.load();
    while (current != kStop && !reached(current, round) && !member.requested.compare_exchange_weak(current, round)) {
    }
    futex_wake(member.requested, 1);
  });
  return round;
}

template <class ForEach>
std::vector<DeadlineCrew::Outcome> DeadlineCrew::wait_round(ForEach each, std::uint32_t round, Clock::time_point deadline,
                                                            bool spin) noexcept {
  auto& s = *shared_;
  const auto all_done = [&] {
    bool done = true;
    each([&](const Shared::Member& m) {
      done = done && (m.retired.load(std::memory_order_acquire) || reached(m.finished.load(std::memory_order_acquire), round));
    });
    return done;
  };
  // The watcher never spins: at the members' priority it would keep one of them off its core.
  const auto spin_until = spin ? std::min(deadline, Clock::now() + kSpinFor) : Clock::time_point{};
  while (spin && !all_done() && Clock::now() < spin_until) {
  }
  for (;;) {
    const std::uint32_t seen = s.completions.load(std::memory_order_acquire);
    if (all_done()) break;
    const auto left = deadline - Clock::now();
    if (left <= Clock::duration::zero()) break;
    const auto ns = std::chrono::duration_cast<std::chrono::nanoseconds>(left).count();
    const timespec timeout{static_cast<time_t>(ns / 1'000'000'000), static_cast<long>(ns % 1'000'000'000)};
    futex_wait(s.completions, seen, &timeout);
  }

  std::vector<DeadlineCrew::Outcome> outcomes;
  try {
    each([&](const Shared::Member& member) {
      auto& outcome = outcomes.emplace_back();
      outcome.name = member.name;
      if (member.retired.load(std::memory_order_acquire)) {
        outcome.state = State::Failed;
        outcome.error = member.failure;
      } else if (reached(member.finished.load(std::memory_order_acquire), round)) {
        outcome.state = State::Done;
        outcome.latency_us = member.latency_us.load();
      }
    });
  } catch (...) {  // no memory for the report: the calls themselves were started
  }
  return outcomes;
}

std::vector<DeadlineCrew::Outcome> DeadlineCrew::run_all(std::chrono::steady_clock::time_point deadline) noexcept {
  auto& members = shared_->members;
  const auto all = [&](auto&& f) {
    for (auto& member : members) f(member);
  };
  return wait_round(all, start_round(all), deadline);
}

void DeadlineCrew::start_all() noexcept {
  auto& s = *shared_;
  const auto all = [&](auto&& f) {
    for (auto& member : s.members) f(member);
  };
  if (!watcher_.joinable()) {
    start_round(all);
    return;
  }
  // One wake-up on the caller's path (each costs an inter-processor interrupt, which on a VM is a trip through the
  // hypervisor): the watcher starts the round, waking the members, from its own thread.
  std::uint32_t asked = s.watched.load(std::memory_order_relaxed);
  do {
    if (asked + 1 == kStop) return;  // shutting down (or at the wrap point: the next request asks again)
  } while (!s.watched.compare_exchange_weak(asked, asked + 1, std::memory_order_release, std::memory_order_relaxed));
  futex_wake(s.watched, 1);
}

void DeadlineCrew::watch(std::chrono::milliseconds within, std::function<void(std::vector<Outcome>)> report) {
  if (watcher_.joinable()) throw std::logic_error("DeadlineCrew::watch: already watching");
  shared_->watch_within = within;
  shared_->report = std::move(report);
  watcher_ = std::thread([this] { watch_rounds(); });
}

// The watcher: sleeps until start_all() asks for a round, starts it and waits for it (up to watch_within), then
// reports it. Requests that come while it waits are served by one round right after.
void DeadlineCrew::watch_rounds() noexcept {
  auto& s = *shared_;
  pthread_setname_np(pthread_self(), (role_.substr(0, 12) + ".w").c_str());
  if (on_thread_start_) on_thread_start_();  // as prompt as the members it watches
  const auto all = [&](auto&& f) {
    for (auto& member : s.members) f(member);
  };
  std::uint32_t seen = 0;
  for (;;) {
    std::uint32_t asked = s.watched.load(std::memory_order_acquire);
    while (asked == seen) {
      futex_wait(s.watched, seen, nullptr);
      asked = s.watched.load(std::memory_order_acquire);
    }
    if (asked == kStop) return;
    seen = asked;
    const std::uint32_t round = start_round(all);
    s.watch_started.store(asked, std::memory_order_release);
    auto outcomes = wait_round(all, round, Clock::now() + s.watch_within, /*spin=*/false);
    try {
      s.report(std::move(outcomes));
    } catch (...) {  // a report that fails (no memory) loses only the report
    }
  }
}

std::vector<DeadlineCrew::Outcome> DeadlineCrew::run_some(std::span<const std::size_t> indices,
                                                          std::chrono::steady_clock::time_point deadline) noexcept {
  auto& members = shared_->members;
  const auto some = [&](auto&& f) {
    for (const auto index : indices)
      if (index < members.size()) f(members[index]);
  };
  return wait_round(some, start_round(some), deadline);
}

bool DeadlineCrew::quiesce(std::chrono::milliseconds grace) noexcept {
  const auto until = Clock::now() + grace;
  while (!shared_->quiet()) {
    if (Clock::now() >= until) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return true;
}

std::size_t DeadlineCrew::size() const noexcept { return shared_->members.size(); }

std::string_view to_string(DeadlineCrew::State state) noexcept {
  switch (state) {
    case DeadlineCrew::State::Done: return "done";
    case DeadlineCrew::State::Pending: return "pending";
    case DeadlineCrew::State::Failed: return "failed";
  }
  return "pending";
}

}  // namespace rcand
