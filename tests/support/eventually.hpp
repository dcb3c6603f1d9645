#pragma once
// Polls a condition that has no event of its own (a dial's failure, a client's connected flag, a reading going
// stale) until it holds or the deadline passes. The deadline is generous: this waits on an outcome, it never times one.
#include <chrono>
#include <thread>

namespace rcand::test {

template <class Condition>
bool eventually(Condition condition, std::chrono::milliseconds deadline = std::chrono::seconds(20),
                std::chrono::milliseconds poll = std::chrono::milliseconds(5)) {
  const auto until = std::chrono::steady_clock::now() + deadline;
  while (!condition()) {
    if (std::chrono::steady_clock::now() > until) return false;
    std::this_thread::sleep_for(poll);
  }
  return true;
}

}  // namespace rcand::test
