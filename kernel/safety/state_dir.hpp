// rcand's state across restarts (runtime.state_dir), so that a crash never brings the robot back unlatched:
//   lock       flock'ed while rcand runs: one rcand per state dir
//   running    the running marker, written (fsync'd) at start and removed only by a clean shutdown: a start that
//              finds it knows the last run ended uncleanly (kill -9, a crash, power loss) and starts latched
//   estop.json the e-stop latch record {"latched", "reason", "source", "since_ms"}, replaced atomically (temp file,
//              fsync, rename, fsync of the directory) whenever the latch changes; a start that finds it latched (or
//              cannot read it) starts latched
// Writing never happens on the stop path: latch_changed() only wakes a writer thread, which writes the latest state.
// A stop that is not yet written when rcand dies is covered by the running marker.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

namespace rcand::kernel {

class StateDir {
 public:
  struct LatchRecord {
    bool latched = false;
    std::string reason, source;
    std::int64_t since_ms = 0;
  };
  struct Previous {
    bool unclean_exit = false;         // the running marker was there
    std::string marker;                // what it said (pid, start time), when it was
    std::optional<LatchRecord> latch;  // the last latch record, when there is one (unreadable: latched, reason says so)
  };

  // Opens `dir` (created with its parents when missing, mode 0750), locks it, reads what the last run left and
  // writes the running marker. Throws std::runtime_error naming runtime.state_dir when any of it fails.
  explicit StateDir(std::filesystem::path dir);
  // Stops the writer. Leaves the running marker: only clean_exit() removes it.
  ~StateDir();
  StateDir(const StateDir&) = delete;
  StateDir& operator=(const StateDir&) = delete;

  const Previous& previous() const noexcept { return previous_; }
  const std::filesystem::path& path() const noexcept { return dir_; }

  // Startup: the writer thread writes what `current` returns whenever latch_changed() is called.
  void start_writer(std::function<LatchRecord()> current);
  // Any thread (the stop path too): never blocks on I/O; the latest state is written soon after.
  void latch_changed() noexcept;
  // Clean shutdown: stops the writer, writes `last` synchronously, then removes the running marker (fsync'd).
  void clean_exit(const LatchRecord& last) noexcept;

  // The latch record file's text for `record`, and the record from a file's text (nullopt when unreadable).
  static std::string format(const LatchRecord& record);
  static std::optional<LatchRecord> parse(const std::string& text);

 private:
  std::filesystem::path dir_;
  int lock_fd_ = -1;
  Previous previous_;
  std::mutex mutex_;  // the writer's wake-up only, never held around I/O
  std::condition_variable wake_;
  bool dirty_ = false, stopping_ = false;
  std::function<LatchRecord()> current_;
  std::thread writer_;

  bool write_latch(const LatchRecord& record) noexcept;
  void stop_writer() noexcept;
};

}  // namespace rcand::kernel
