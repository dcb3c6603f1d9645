// The stop path's helpers: one pre-created thread per plugin call the stop path must make (each actuator's halt(),
// each capability's on_estop()), and a leader thread that makes a round's calls one after another, so a round wakes
// one thread; the calls the leader has not claimed within a short hand-off run on their own threads, in parallel.
// The stop path waits for them only up to a deadline: a call that hangs delays neither the stop's answer nor (beyond
// the hand-off) the other calls; a call that throws out of its noexcept hook is caught by the TerminateTrap and
// reported, and that member is retired for good (the thread it threw on parks).
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <thread>
#include <vector>

namespace rcand {

class DeadlineCrew {
 public:
  struct Job {
    std::string name;
    std::function<void()> call;  // a noexcept plugin hook; runs on this job's own thread only
  };
  enum class State { Done, Pending, Failed };
  struct Outcome {
    std::string name;
    State state = State::Pending;
    std::int64_t latency_us = 0;  // Done: how long the call took
    std::string error;            // Failed: what it threw
  };

  // How long the leader has to claim a round's calls before the members' own threads are woken for the rest: what
  // a call that hangs on the leader delays the others by (the halts' deadline is 100 ms).
  static constexpr std::chrono::microseconds kHandOff{200};

  // Starts one thread per job, named "<role>.<n>", and with two jobs or more the leader, "<role>.l"; each runs
  // `on_thread_start` first (when set).
  DeadlineCrew(std::string role, std::vector<Job> jobs, std::function<void()> on_thread_start = {},
               std::chrono::microseconds hand_off = kHandOff);
  // Joins the idle threads; a thread still inside a plugin call (or parked) is detached and keeps the shared state.
  ~DeadlineCrew();
  DeadlineCrew(const DeadlineCrew&) = delete;
  DeadlineCrew& operator=(const DeadlineCrew&) = delete;

  // Any thread, concurrently too; lock-free, allocates only the result. Starts every job (a member still busy with an earlier
  // round runs it again right after) and waits until each has finished a round started after this call, or failed,
  // or until `deadline`, whichever comes first.
  std::vector<Outcome> run_all(std::chrono::steady_clock::time_point deadline) noexcept;
  // run_all for the members at `indices` only (outcomes in that order; an index out of range is skipped): the
  // others are neither started nor waited for.
  std::vector<Outcome> run_some(std::span<const std::size_t> indices, std::chrono::steady_clock::time_point deadline) noexcept;
  // Off the caller's path: what a round asked for by start_all() ended with, handed to `report` on the crew's watcher
  // thread once every member finished it or failed, or `within` after it started. Startup only, before start_all().
  void watch(std::chrono::milliseconds within, std::function<void(std::vector<Outcome>)> report);
  // Any thread; lock-free, allocates nothing, waits for nothing: starts every job (as run_all does) and returns.
  // With watch(), it wakes only the watcher, which starts the round and reports it (requests that come while it
  // watches one round: one more round right after).
  void start_all() noexcept;
  // Waits up to `grace` for members still inside a plugin call; true when none is (parked members do not count).
  bool quiesce(std::chrono::milliseconds grace) noexcept;
  std::size_t size() const noexcept;

 private:
  struct Shared;
  // Starts a round for the members `each` visits (its number), and waits for one; defined (and only used) in the .cpp.
  struct Started {
    std::uint32_t round = 0;
    bool led = false;        // the leader was woken (the members' threads are the waiter's to wake at the hand-off)
    bool on_caller = false;  // ... on the caller's CPU, which the caller then yields to it by sleeping at once
  };
  template <class ForEach> Started start_round(ForEach each, bool lead) noexcept;
  template <class ForEach>
  std::vector<Outcome> wait_round(ForEach each, Started started, std::chrono::steady_clock::time_point deadline,
                                  bool spin = true) noexcept;
  void watch_rounds() noexcept;
  std::shared_ptr<Shared> shared_;
  std::string role_;
  std::function<void()> on_thread_start_;
  std::chrono::microseconds hand_off_;
  std::thread watcher_;  // watch() only
};

std::string_view to_string(DeadlineCrew::State state) noexcept;

}  // namespace rcand
