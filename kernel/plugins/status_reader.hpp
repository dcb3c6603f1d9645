// Plugin status() calls, off the I/O threads. status() runs for a request and must not block; one that blocks anyway
// would hold an I/O thread, and with two of those held nobody reads POST /api/stop any more. So each instance's
// status() runs on a thread of its own (a DeadlineCrew member) and is waited for up to kStatusDeadline; a late call
// answers its last value. A call still running kHungAfter after it began is hung: the reader that finds it so marks
// the instance failed, logs it once, and it is never asked again. (A late call is not a hung one: on a loaded board
// a status() thread can wait a few hundred ms for a core, and that must not fail the capability for good.)
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "libs/base/deadline_crew.hpp"
#include "kernel/safety/instance_health.hpp"

namespace rcand::kernel {

class StatusReader {
 public:
  struct Source {
    std::string who;                         // "plugin <id> capability <name>", for the log
    std::function<nlohmann::json()> status;  // the plugin's status(); may throw (logged, no status)
    InstanceHealth* health;                  // marked failed when status() misses the deadline
  };
  // One source's last answer; shared with its crew job, since a thread still inside a hung status() outlives the
  // reader.
  struct Slot {
    std::mutex mutex;
    std::optional<nlohmann::json> latest;  // the last value a status() call returned (nullopt: it threw)
    std::atomic<bool> in_flight{false};    // a reader asked and the call has not returned yet
    std::atomic<std::int64_t> asked_ns{0};  // steady-clock time the call in flight was asked
    std::atomic<bool> hung{false};
  };
  // Well past any status() that keeps its contract (microseconds), and short enough that both I/O threads held by
  // a hanging one still leave a stop inside its 500 ms.
  static constexpr std::chrono::milliseconds kStatusDeadline{250};
  // Far past any scheduling delay: only a status() that blocks is still running after this.
  static constexpr std::chrono::milliseconds kHungAfter{2000};

  explicit StatusReader(std::vector<Source> sources);
  StatusReader(const StatusReader&) = delete;
  StatusReader& operator=(const StatusReader&) = delete;

  // Any thread. The status of each source at `indices`, read on the crew (DeadlineCrew: a slow one does not hold
  // up the others beyond its hand-off): nullopt for one that threw or hung; a
  // late one's last value (nullopt before its first answer). A source whose call is still in flight is not asked
  // again: it answers its last value at once, so concurrent readers of a hung status() hold I/O threads for one
  // deadline in all, not one each.
  std::vector<std::optional<nlohmann::json>> read(std::span<const std::size_t> indices);
  std::optional<nlohmann::json> read(std::size_t index);
  // True when no status() call is still running after `grace`; false means one hangs, and the objects it reads
  // must never be destroyed.
  bool quiesce(std::chrono::milliseconds grace) noexcept;

 private:
  void mark_hung(std::size_t index, const std::string& why);

  std::vector<Source> sources_;
  std::vector<std::shared_ptr<Slot>> slots_;
  DeadlineCrew crew_;
};

}  // namespace rcand::kernel
