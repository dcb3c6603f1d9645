// rcand's state across restarts (runtime.state_dir), so that a crash never brings the robot back unlatched:
//   lock       flock'ed while rcand runs, before anything else it does: one rcand per state dir; says who holds it
//   running    the running marker, written (fsync'd) at start and removed only by a clean shutdown: a start that
//              finds it knows the last run ended uncleanly (kill -9, a crash, power loss) and starts latched
//   estop.json the e-stop latch record {"latched", "reason", "source", "since_ms", "seq"}, replaced atomically (temp
//              file, fsync, rename, fsync of the directory) whenever the latch changes; a start that finds it latched
//              (or cannot read it) starts latched
//   estop.slot the same record, rewritten in place (padded to a fixed size) just before estop.json, in space written
//              at start: a disk that fills up while rcand runs cannot lose it (estop.json's new file then fails, this
//              does not). A start reads the newer (higher "seq") of the two that parse.
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

  // Opens `dir` (created with its parents when missing, mode 0750), locks it and reads what the last run left; writes
  // nothing else (a refused start touches nothing). Throws std::runtime_error naming runtime.state_dir when any of it
  // fails, and naming the rcand that holds the lock when another one does.
  explicit StateDir(std::filesystem::path dir);
  // Stops the writer. Leaves the running marker: only clean_exit() removes it.
  ~StateDir();
  StateDir(const StateDir&) = delete;
  StateDir& operator=(const StateDir&) = delete;

  const Previous& previous() const noexcept { return previous_; }
  const std::filesystem::path& path() const noexcept { return dir_; }

  // Startup, once serving is decided: writes the running marker and reserves estop.slot's space. Throws
  // std::runtime_error naming runtime.state_dir when it cannot (a full disk, a read-only one).
  void mark_running();
  // Startup: the writer thread writes what `current` returns whenever latch_changed() is called.
  void start_writer(std::function<LatchRecord()> current);
  // Any thread (the stop path too): never blocks on I/O; the latest state is written soon after.
  void latch_changed() noexcept;
  // Clean shutdown: stops the writer, writes `last` synchronously, then removes the running marker (fsync'd).
  void clean_exit(const LatchRecord& last) noexcept;

  // The latch record file's text for `record` (numbered `seq`), and the record from a file's text (nullopt when
  // unreadable; `seq` gets its number, 0 when it has none).
  static std::string format(const LatchRecord& record, std::uint64_t seq = 0);
  static std::optional<LatchRecord> parse(const std::string& text, std::uint64_t* seq = nullptr);
  static constexpr std::size_t kSlotBytes = 4096;  // estop.slot's fixed size

 private:
  std::filesystem::path dir_;
  int lock_fd_ = -1;
  int slot_fd_ = -1;       // estop.slot, open from mark_running()
  std::uint64_t seq_ = 0;  // the last record's number; the writer's (and clean_exit's, after it) only
  Previous previous_;
  std::mutex mutex_;  // the writer's wake-up only, never held around I/O
  std::condition_variable wake_;
  bool dirty_ = false, stopping_ = false;
  std::function<LatchRecord()> current_;
  std::thread writer_;

  void take_lock(const std::filesystem::path& lock_file);
  void read_previous();
  std::string write_slot(const std::string& text) noexcept;
  bool write_latch(const LatchRecord& record) noexcept;
  void stop_writer() noexcept;
};

}  // namespace rcand::kernel
