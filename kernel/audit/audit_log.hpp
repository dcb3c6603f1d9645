// The audit log (docs/protocol.md §6.3): every command and config change is recorded BEFORE dispatch, then its outcome
// (ok | blocked | error) is filled in. Bounded in memory; every entry is also written to the "kernel.audit" log
// (at most kLogLinesPerSecond lines per principal, then one "suppressed" line). Every text field is bounded
// (bounded_text: length, valid UTF-8, no control characters) as it is recorded, whoever supplied it.
// Nothing is lost silently: entries rotated out of memory are counted (`dropped` in GET /api/audit), and with
// runtime.audit_file every entry is appended to that file as JSON lines, two per entry: {"kind":"entry",
// "outcome":"pending",...} written by record() before dispatch, then {"kind":"outcome",...} (same seq, the final
// outcome) written by finish(). An entry whose outcome line is missing was in flight when rcand died. Each line is
// one write(2) on an O_APPEND descriptor: a crash of rcand (kill -9, abort) loses no line already recorded; lines
// are not fsync'd one by one (a power loss may lose the last ones), the file is fsync'd when rotated and closed.
// The file rotates by size: FILE -> FILE.1 -> ... -> FILE.<keep>, and the sequence continues from the last seq
// found in FILE (or FILE.1) at startup, so seq never restarts while the files are kept.
#pragma once

#include <nlohmann/json.hpp>

#include <atomic>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <mutex>
#include <string>

#include "libs/base/logging.hpp"
#include "rcand/sdk/clock.hpp"

namespace rcand::kernel {

struct AuditEntry {
  std::uint64_t seq = 0;
  std::string principal, ruri, message_id, event;
  std::int64_t timestamp_ms = 0;
  std::string outcome = "pending";  // until dispatch finishes: ok | blocked | error
  std::string detail;               // why it was blocked or failed
  nlohmann::json note;              // null, or keys the requesting plugin added (the chat's "ai"), checked by
                                    // KernelRequestDispatcher: lowercase names, none of the above, bounded
};

class AuditLog {
 public:
  static constexpr std::size_t kFieldLimit = 200;          // principal, ruri, message_id
  static constexpr std::size_t kEventLimit = 300;          // "POST /api/action <type>"
  static constexpr std::size_t kDetailLimit = 2000;        // why it was blocked or failed
  static constexpr std::uint32_t kLogLinesPerSecond = 20;  // "kernel.audit" log lines per principal
  static constexpr std::uintmax_t kDefaultMaxFileBytes = 64ull << 20;
  static constexpr int kDefaultKeepFiles = 4;

  explicit AuditLog(std::size_t capacity = 10000) : capacity_(capacity) {}
  ~AuditLog();
  AuditLog(const AuditLog&) = delete;
  AuditLog& operator=(const AuditLog&) = delete;
  // Records the entry (every text field bounded), appends its pending line to the file, and returns its sequence number.
  std::uint64_t record(AuditEntry entry);
  // Startup: whose log this is (every entry's ruri) and the clock of its timestamps.
  void identify(std::string robot_ruri, const sdk::Clock& clock);
  // The one audit call of request paths: records "pending" for `principal` now and returns the seq that finish()
  // completes. Before dispatch, always (docs/protocol.md §6.3).
  std::uint64_t begin(const std::string& principal, const std::string& message_id, std::string event,
                      nlohmann::json note = nullptr);
  void finish(std::uint64_t seq, std::string outcome, std::string detail = {});
  // {"entries":[...]} newest first, at most `limit`.
  nlohmann::json to_json(std::size_t limit) const;
  // Entries recorded in this run (seq continues the file's, so seq and total differ after a restart).
  std::uint64_t total() const;
  // Entries rotated out of memory so far.
  std::uint64_t dropped() const;
  // Startup: append every entry to `file` (created if missing), rotating it when a line would take it past
  // `max_bytes` and keeping `keep` rotated files; the sequence continues after the last seq in the file. Throws
  // std::runtime_error (naming runtime.audit_file) when it cannot.
  void persist_to(const std::filesystem::path& file, std::uintmax_t max_bytes = kDefaultMaxFileBytes,
                  int keep = kDefaultKeepFiles);

 private:
  const std::size_t capacity_;
  std::uint64_t dropped_ = 0;
  std::mutex file_mutex_;                // the file's own lock: writing never holds mutex_
  int fd_ = -1;                          // under file_mutex_
  std::atomic<bool> persisting_{false};  // set once fd_ and file_name_ are (file_name_ never changes afterwards)
  std::string file_name_;
  std::uintmax_t file_bytes_ = 0, max_bytes_ = kDefaultMaxFileBytes;
  int keep_ = kDefaultKeepFiles;
  LogRateLimiter log_limit_{kLogLinesPerSecond};

  void append_line(std::uint64_t seq, const nlohmann::json& line) noexcept;
  int rotate_locked() noexcept;  // returns the old descriptor, to be fsync'd and closed outside the lock
  bool log_line_allowed(const std::string& principal) noexcept;
  std::string robot_ruri_;
  const sdk::Clock* clock_ = nullptr;
  mutable std::mutex mutex_;  // held for a copy or an assignment only; never around I/O or plugin calls
  std::deque<AuditEntry> entries_;
  std::uint64_t next_seq_ = 1;
  std::uint64_t first_seq_ = 1;  // this run's first seq (it continues the file's): total = next_seq_ - first_seq_
};

}  // namespace rcand::kernel
