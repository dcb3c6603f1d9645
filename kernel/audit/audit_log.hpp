// The audit log (docs/protocol.md §6.3): every command and config change is recorded BEFORE dispatch, then its outcome
// (ok | blocked | error) is filled in. Bounded in memory; every entry is also written to the "kernel.audit" log
// (at most kLogLinesPerSecond lines per principal, then one "suppressed" line). Every text field is bounded
// (bounded_text: length, valid UTF-8, no control characters) as it is recorded, whoever supplied it.
//
// Two retentions, so that stops - which anyone with a token may send, never rate-limited - can never push anything
// else out (issue 28 #7): stops (POST /api/stop, POST /api/swarm/<node>/stop, a plugin's e-stop request) are kept in
// a ring of their own (stop_capacity) and, with runtime.audit_file, a file of their own (stops_file_for); every other
// entry (commands, clears, config changes, refusals) in the main ring and file. A stop that repeats one already
// recorded while the e-stop stays latched - same principal, same event, no clear since - is coalesced into that
// entry (its `count`, `last_ms`, `last_message_id`) instead of making a new one: still audited before the latch
// (§6.3), but a flood of repeats is one entry.
//
// Nothing is lost silently: entries rotated out of memory are counted (`dropped` in GET /api/audit), and with
// runtime.audit_file every entry is appended to its file as JSON lines, two per entry: {"kind":"entry",
// "outcome":"pending",...} written by record() before dispatch, then {"kind":"outcome",...} (same seq, the final
// outcome) written by finish(). An entry whose outcome line is missing was in flight when rcand died. A coalesced
// entry's count reaches the stops file as {"kind":"repeat","seq","count","last_ms","last_message_id"} lines: one
// with the first repeat, then at most one per kRepeatLineGapMs while repeats go on, and the final count when the
// e-stop is cleared or rcand exits (a crash may lose the last second's count, never an entry). Each line is one
// write(2) on an O_APPEND descriptor (libs/base/rotating_file.hpp). Each file rotates by size: FILE -> FILE.1 ->
// ... -> FILE.<keep>; seq is one sequence over both files (merge them by seq for the whole history), and it
// continues from the last seq found in either file (or its .1) at startup, so seq never restarts while files are kept.
#pragma once

#include <nlohmann/json.hpp>

#include <cstdint>
#include <deque>
#include <filesystem>
#include <mutex>
#include <string>
#include <unordered_map>
#include <unordered_set>

#include "libs/base/logging.hpp"
#include "libs/base/rotating_file.hpp"
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
  std::uint64_t count = 1;          // stops this entry stands for (> 1: repeats coalesced into it)
  std::int64_t last_ms = 0;         // with count > 1: when the latest repeat came, and its message id
  std::string last_message_id{};
};

// Which ring (and file) an entry is kept in.
enum class AuditRetention { Record, Stop };

class AuditLog {
 public:
  static constexpr std::size_t kFieldLimit = 200;          // principal, ruri, message_id
  static constexpr std::size_t kEventLimit = 300;          // "POST /api/action <type>"
  static constexpr std::size_t kDetailLimit = 2000;        // why it was blocked or failed
  static constexpr std::uint32_t kLogLinesPerSecond = 20;  // "kernel.audit" log lines per principal
  static constexpr std::size_t kDefaultCapacity = 10000;
  static constexpr std::size_t kDefaultStopCapacity = 1000;
  static constexpr std::int64_t kRepeatLineGapMs = 1000;  // a coalesced entry's count: at most one line a second
  static constexpr std::uintmax_t kDefaultMaxFileBytes = 64ull << 20;
  static constexpr int kDefaultKeepFiles = 4;

  explicit AuditLog(std::size_t capacity = kDefaultCapacity, std::size_t stop_capacity = kDefaultStopCapacity)
      : records_{capacity}, stops_{stop_capacity} {}
  ~AuditLog();  // writes repeat counts not yet in the file
  AuditLog(const AuditLog&) = delete;
  AuditLog& operator=(const AuditLog&) = delete;
  // Records the entry (every text field bounded) in `retention`, appends its pending line to the file, and returns
  // its sequence number.
  std::uint64_t record(AuditEntry entry, AuditRetention retention = AuditRetention::Record);
  // Startup: whose log this is (every entry's ruri) and the clock of its timestamps.
  void identify(std::string robot_ruri, const sdk::Clock& clock);
  // The one audit call of request paths: records "pending" for `principal` now and returns the seq that finish()
  // completes. Before dispatch, always (docs/protocol.md §6.3).
  std::uint64_t begin(const std::string& principal, const std::string& message_id, std::string event,
                      nlohmann::json note = nullptr, AuditRetention retention = AuditRetention::Record);
  // A stop, before its latch: as begin() in the stops' retention, except that while `latched` (the e-stop was
  // latched before this stop) a repeat of this principal's stop of the same event since the last clear is
  // coalesced into that entry (count, last_ms, last_message_id; no log line, at most one file line a second) and 0
  // is returned, which finish() ignores. One lock, as for any entry; no I/O beyond a new entry's.
  std::uint64_t begin_stop(const std::string& principal, const std::string& message_id, std::string event, bool latched,
                           std::string detail = {});
  // The e-stop was cleared: the next stop starts a new entry; counts not yet in the file are written now.
  void end_repeats() noexcept;
  // Fills in the outcome of `seq` (0: a coalesced repeat, nothing to do).
  void finish(std::uint64_t seq, std::string outcome, std::string detail = {});
  // {"entries":[...]} newest first (both retentions, by seq), at most `limit`.
  nlohmann::json to_json(std::size_t limit) const;
  // Entries recorded in this run (seq continues the file's, so seq and total differ after a restart).
  std::uint64_t total() const;
  // Entries rotated out of memory so far (both retentions).
  std::uint64_t dropped() const;
  // Startup: append every entry to `file` (stops to stops_file_for(file)), created if missing, rotating each when a
  // line would take it past `max_bytes` and keeping `keep` rotated files; the sequence continues after the last seq
  // in them. Throws std::runtime_error (naming runtime.audit_file) when it cannot.
  void persist_to(const std::filesystem::path& file, std::uintmax_t max_bytes = kDefaultMaxFileBytes,
                  int keep = kDefaultKeepFiles);
  // audit.jsonl -> audit.stops.jsonl (beside it).
  static std::filesystem::path stops_file_for(const std::filesystem::path& file);

 private:
  struct Ring {
    std::size_t capacity;
    std::deque<AuditEntry> entries{};  // ascending seq (not contiguous: the other ring has the rest)
    std::uint64_t dropped = 0;
  };
  struct RepeatLine {  // a coalesced entry's count, to be written to the stops file
    std::uint64_t seq = 0, count = 0;
    std::int64_t last_ms = 0;
    std::string last_message_id{};
  };
  struct Coalesced {  // the entry a principal's repeated stop is coalesced into, until the next clear
    std::uint64_t seq = 0;
    std::uint64_t count_in_file = 1;
    std::int64_t written_ms = 0;  // when its count was last written (its entry line, then repeat lines)
  };
  static constexpr std::size_t kMaxCoalesced = 1024;  // principals x stop events with an open entry

  RotatingFile records_file_, stops_file_;
  LogRateLimiter log_limit_{kLogLinesPerSecond};
  std::string robot_ruri_;
  const sdk::Clock* clock_ = nullptr;
  mutable std::mutex mutex_;  // held for a copy or an assignment only; never around I/O or plugin calls
  Ring records_, stops_;
  std::unordered_map<std::string, Coalesced> coalesced_;  // "principal\nevent" -> its open entry (stops_)
  std::unordered_set<std::uint64_t> evicted_stops_;       // stops that left memory before their outcome (bounded)
  std::uint64_t next_seq_ = 1;
  std::uint64_t first_seq_ = 1;  // this run's first seq (it continues the file's): total = next_seq_ - first_seq_

  std::int64_t now_ms() const;
  void bound_fields(AuditEntry& entry) const;
  std::uint64_t store_locked(AuditEntry& entry, AuditRetention retention);
  AuditEntry* find_locked(std::uint64_t seq, bool* is_stop = nullptr);
  bool coalesce_locked(const std::string& key, const std::string& message_id, std::int64_t now, RepeatLine& line);
  void write_entry(const AuditEntry& entry, AuditRetention retention) noexcept;
  void write_repeat(const RepeatLine& line) noexcept;
  void append_line(RotatingFile& file, std::uint64_t seq, const nlohmann::json& line) noexcept;
  bool log_line_allowed(const std::string& principal) noexcept;
};

}  // namespace rcand::kernel
