#include "libs/base/deadline_crew.hpp"

#include <linux/futex.h>
#include <pthread.h>
#include <sched.h>
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
// When the calls run on other CPUs (the members' threads, or a leader that could not be pinned to the caller's),
// the stop path spins this long before sleeping: a healthy halt() returns within microseconds, and sleeping would
// add a wake-up to every stop. After it, the stop path sleeps on a futex until a member finishes or the deadline.
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

// Lock-free between the stop path and the members: one atomic per fact, so starting a round is a store per member
// and one futex wake, and the stop path never waits for a lock a member holds.
//
// Who makes the calls: a round wakes one thread, the leader, which makes the round's calls one after another; each
// member's own thread is woken only for the calls still unclaimed after kHandOff (a leader inside a call that hangs)
// or when the leader is unavailable (inside a call from an earlier round, or parked after a throw). On a VM each
// wake-up of a sleeping thread is a trip through the hypervisor: waking three halt threads on two vCPUs was most of
// the stop's halt time, while a healthy halt() returns within microseconds. A call never runs twice at once: whoever
// runs it holds its claim, and re-runs it for a round asked while it ran.
struct DeadlineCrew::Shared {
  struct Member {
    std::string name;
    std::function<void()> call;
    std::atomic<std::uint32_t> requested{0};  // the latest round asked of it (kStop: exit)
    std::atomic<std::uint64_t> claim{0};      // (the latest round a thread took on << 1) | 1 while its call runs
    std::atomic<std::uint32_t> finished{0};   // the latest round it completed
    std::atomic<std::int64_t> latency_us{0};
    std::atomic<bool> retired{false};  // the call threw out of noexcept: never called again
    std::string failure;               // written before `retired` is set, read after it is seen
  };
  // A thread that makes members' calls: each member's own, and the leader.
  struct Runner {
    std::thread thread;
    std::atomic<Member*> current{nullptr};  // whose call runs on it now
    std::atomic<bool> parked{false};        // a call threw out of noexcept on it: parked for good
  };

  std::atomic<std::uint32_t> round{0};
  std::atomic<std::uint32_t> completions{0};  // bumped whenever a member finishes or retires (woken: see sleepers)
  std::atomic<std::uint32_t> sleepers{0};     // callers asleep on `completions`: a call's end wakes only when one is
  std::deque<Member> members;                 // deques: members and runners never move, threads hold references
  std::deque<Runner> runners;                 // runners[i] is members[i]'s own thread
  Runner* leader = nullptr;                   // a crew of two or more only
  std::atomic<pid_t> leader_tid{0};           // set by the leader as it starts
  std::atomic<int> leader_cpu{-1};            // the CPU the leader is pinned to (-1: not pinned)
  std::atomic<std::uint32_t> leader_asked{0};  // bumped (and woken) for each round the leader is to run
  std::atomic<bool> exiting{false};
  // watch(): counts start_all()'s requests (kStop: the watcher exits), and what the watcher does with a round.
  std::atomic<std::uint32_t> watched{0};
  std::atomic<std::uint32_t> watch_started{0};  // the latest request the watcher has turned into a round
  std::chrono::milliseconds watch_within{0};
  std::function<void(std::vector<Outcome>)> report;

  bool take(Member& member, Runner& runner) noexcept;
  // A throw out of a noexcept call on the runner's thread: that member is retired, and the runner parks for good.
  TerminateTrap trap_for(Runner& runner) {
    return TerminateTrap([this, &runner](std::string_view what) {
      if (auto* member = runner.current.load()) {
        member->failure.assign(what);
        member->retired.store(true, std::memory_order_release);
      }
      runner.parked.store(true, std::memory_order_release);
      completed();
    });
  }
  void serve(Member& member, Runner& runner);
  void lead();
  // A waiter counts itself in `sleepers` before it compares `completions` (both sequentially consistent), so either it
  // sees this bump, or this sees it counted: no wake is lost, and a caller still spinning costs the call no syscall.
  void completed() noexcept {
    completions.fetch_add(1);
    if (sleepers.load() != 0) futex_wake(completions, INT_MAX);
  }
  bool leader_available() const noexcept {
    return leader != nullptr && !leader->parked.load(std::memory_order_acquire) && leader->current.load() == nullptr;
  }
  // No member inside a call or owed one, and no request the watcher has yet to start: a crew about to be torn down
  // (a plugin reload right after a stop) must not have a round it still owes.
  bool quiet() const noexcept {
    const std::uint32_t asked = watched.load(std::memory_order_acquire);
    if (asked != kStop && watch_started.load(std::memory_order_acquire) != asked) return false;
    return std::all_of(members.begin(), members.end(), [](const Member& m) {
      return m.retired.load() || ((m.claim.load() & 1) == 0 && reached(m.finished.load(), m.requested.load()));
    });
  }
};

// Claims the member's latest round and runs its call on `runner`, again for a round asked meanwhile; false when
// there was nothing to claim (done, or running on another thread, which then runs what was asked meanwhile).
bool DeadlineCrew::Shared::take(Member& member, Runner& runner) noexcept {
  bool ran = false;
  for (;;) {
    const std::uint32_t round = member.requested.load();
    if (round == kStop || member.retired.load(std::memory_order_acquire)) return ran;
    std::uint64_t claim = member.claim.load();
    if ((claim & 1) != 0 || reached(static_cast<std::uint32_t>(claim >> 1), round)) return ran;
    if (!member.claim.compare_exchange_strong(claim, (std::uint64_t{round} << 1) | 1)) continue;
    runner.current.store(&member);
    const auto start = Clock::now();
    member.call();
    member.latency_us.store(std::chrono::duration_cast<std::chrono::microseconds>(Clock::now() - start).count());
    runner.current.store(nullptr);
    member.finished.store(round, std::memory_order_release);
    member.claim.store(std::uint64_t{round} << 1);  // released, then requested is read again: no round is lost
    completed();
    ran = true;
  }
}

void DeadlineCrew::Shared::serve(Member& member, Runner& runner) {
  TerminateTrap trap = trap_for(runner);
  std::uint32_t seen = 0;
  for (;;) {
    std::uint32_t taken = member.requested.load(std::memory_order_acquire);
    while (taken == seen) {
      futex_wait(member.requested, seen, nullptr);
      taken = member.requested.load(std::memory_order_acquire);
    }
    if (taken == kStop) return;
    seen = taken;
    take(member, runner);
  }
}

void DeadlineCrew::Shared::lead() {
  leader_tid.store(static_cast<pid_t>(::gettid()));
  TerminateTrap trap = trap_for(*leader);
  std::uint32_t seen = 0;
  for (;;) {
    while (leader_asked.load(std::memory_order_acquire) == seen && !exiting.load()) futex_wait(leader_asked, seen, nullptr);
    if (exiting.load()) return;
    seen = leader_asked.load(std::memory_order_acquire);
    for (bool ran = true; ran;) {  // until no member has a round left to claim
      ran = false;
      for (auto& member : members) ran = take(member, *leader) || ran;
    }
  }
}

DeadlineCrew::DeadlineCrew(std::string role, std::vector<Job> jobs, std::function<void()> on_thread_start,
                           std::chrono::microseconds hand_off)
    : shared_(std::make_shared<Shared>()), role_(role), on_thread_start_(on_thread_start), hand_off_(hand_off) {
  auto& s = *shared_;
  for (auto& job : jobs) {
    auto& member = s.members.emplace_back();
    member.name = std::move(job.name);
    member.call = std::move(job.call);
    s.runners.emplace_back();
  }
  const auto start = [&](Shared::Runner& runner, std::string name, auto body) {
    runner.thread = std::thread([shared = shared_, name = name.substr(0, 15), on_thread_start, body] {
      pthread_setname_np(pthread_self(), name.c_str());
      if (on_thread_start) on_thread_start();
      body(*shared);
    });
  };
  for (std::size_t i = 0; i < s.members.size(); ++i)
    start(s.runners[i], role + "." + std::to_string(i),
          [&member = s.members[i], &runner = s.runners[i]](Shared& shared) { shared.serve(member, runner); });
  if (s.members.size() >= 2) {
    s.leader = &s.runners.emplace_back();
    start(*s.leader, role.substr(0, 12) + ".l", [](Shared& shared) { shared.lead(); });
  }
}

DeadlineCrew::~DeadlineCrew() {
  auto& s = *shared_;
  if (watcher_.joinable()) {  // it waits at most watch_within for a round, then sees kStop
    s.watched.store(kStop, std::memory_order_release);
    futex_wake(s.watched, 1);
    watcher_.join();
  }
  for (auto& member : s.members) {
    member.requested.store(kStop, std::memory_order_release);
    futex_wake(member.requested, 1);
  }
  s.exiting.store(true);
  s.leader_asked.fetch_add(1);
  futex_wake(s.leader_asked, 1);
  // A thread inside a plugin call (or parked after a throw) may never come back: it keeps the shared state alive.
  for (auto& runner : s.runners) {
    if (runner.current.load() != nullptr || runner.parked.load()) runner.thread.detach();
    else runner.thread.join();
  }
}

// `each(f)` calls f(member) for every selected member, in the order the outcomes are reported. `lead`: wake the
// leader only (when it is available) and leave the hand-off to the caller's wait_round().
template <class ForEach> DeadlineCrew::Started DeadlineCrew::start_round(ForEach each, bool lead) noexcept {
  auto& s = *shared_;
  Started started;
  started.round = s.round.fetch_add(1) + 1;
  if (started.round == kStop) started.round = s.round.fetch_add(1) + 1;  // kStop is the exit request, never a round
  started.led = lead && s.leader_available();
  each([&](Shared::Member& member) {
    if (member.retired.load(std::memory_order_acquire)) return;
    std::uint32_t current = member.requested.load();
    while (current != kStop && !reached(current, started.round) &&
           !member.requested.compare_exchange_weak(current, started.round)) {
    }
    if (!started.led) futex_wake(member.requested, 1);
  });
  if (started.led) {
    // The leader runs on the caller's CPU, which the caller hands it by sleeping at once (wait_round): a wake-up on
    // the same CPU is a context switch, where one on the other CPU (idle: on a VM, halted) is an interrupt through
    // the hypervisor, 30-90 µs on this project's VMs. Re-pinned only when the caller's CPU changed; where pinning
    // is not allowed, the leader wakes wherever the scheduler puts it and the caller spins as for the members.
    const int cpu = sched_getcpu();
    started.on_caller = cpu >= 0 && cpu == s.leader_cpu.load();
    if (const pid_t tid = s.leader_tid.load(); !started.on_caller && cpu >= 0 && tid != 0) {
      cpu_set_t set;
      CPU_ZERO(&set);
      CPU_SET(cpu, &set);
      started.on_caller = sched_setaffinity(tid, sizeof set, &set) == 0;
      s.leader_cpu.store(started.on_caller ? cpu : -1);
    }
    s.leader_asked.fetch_add(1, std::memory_order_release);
    futex_wake(s.leader_asked, 1);
  }
  return started;
}

template <class ForEach>
std::vector<DeadlineCrew::Outcome> DeadlineCrew::wait_round(ForEach each, Started started, Clock::time_point deadline,
                                                            bool spin) noexcept {
  auto& s = *shared_;
  const std::uint32_t round = started.round;
  const auto finished = [&](const Shared::Member& m) {
    return m.retired.load(std::memory_order_acquire) || reached(m.finished.load(std::memory_order_acquire), round);
  };
  const auto all_done = [&] {
    bool done = true;
    each([&](const Shared::Member& m) { done = done && finished(m); });
    return done;
  };
  const auto now = Clock::now();
  // Whatever is left at the hand-off goes to the members' own threads (a no-op for a call already claimed).
  auto hand_off_at = started.led ? std::min(deadline, now + hand_off_) : Clock::time_point::max();
  // The watcher never spins: at the members' priority it would keep one of them off its core. Nor does a caller
  // whose CPU the leader waits for.
  const auto spin_until = spin && !started.on_caller ? std::min(deadline, now + kSpinFor) : Clock::time_point{};
  while (Clock::now() < spin_until && !all_done()) {
  }
  for (;;) {
    const std::uint32_t seen = s.completions.load(std::memory_order_acquire);
    if (all_done()) break;
    const auto at = Clock::now();
    const bool handing_off = hand_off_at != Clock::time_point::max();
    if (handing_off && (at >= hand_off_at || at >= deadline)) {  // a round is never left with calls nobody will make
      each([&](Shared::Member& m) {
        if (!finished(m)) futex_wake(m.requested, 1);
      });
      hand_off_at = Clock::time_point::max();
    }
    if (at >= deadline) break;
    const auto ns = std::chrono::duration_cast<std::chrono::nanoseconds>(std::min(deadline, hand_off_at) - at).count();
    const timespec timeout{static_cast<time_t>(ns / 1'000'000'000), static_cast<long>(ns % 1'000'000'000)};
    s.sleepers.fetch_add(1);
    futex_wait(s.completions, seen, &timeout);
    s.sleepers.fetch_sub(1);
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
  return wait_round(all, start_round(all, true), deadline);
}

void DeadlineCrew::start_all() noexcept {
  auto& s = *shared_;
  const auto all = [&](auto&& f) {
    for (auto& member : s.members) f(member);
  };
  if (!watcher_.joinable()) {
    start_round(all, false);  // nobody waits to hand off: every member's thread is woken
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
    const auto started = start_round(all, true);
    s.watch_started.store(asked, std::memory_order_release);
    auto outcomes = wait_round(all, started, Clock::now() + s.watch_within, /*spin=*/false);
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
  return wait_round(some, start_round(some, true), deadline);
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
