// The audit log (notes §6.3): every command and config change is recorded BEFORE dispatch, then its outcome
// (ok | blocked | error) is filled in. Bounded in memory; every entry is also written to the "kernel.audit" log.
// Nothing is lost silently: entries rotated out of memory are counted (`dropped` in GET /api/audit), and with
// runtime.audit_file every finished entry is appended to that file as one JSON line, so the file has them all.
#pragma once

#include <nlohmann/json.hpp>

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <deque>
#include <mutex>
#include <string>

namespace rcand::kernel {

struct AuditEntry {
  std::uint64_t seq = 0;
  std::string principal, ruri, message_id, event;
  std::int64_t timestamp_ms = 0;
  std::string outcome = "pending";  // until dispatch finishes: ok | blocked | error
  std::string detail;               // why it was blocked or failed
};

class AuditLog {
 public:
  explicit AuditLog(std::size_t capacity = 10000) : capacity_(capacity) {}
  ~AuditLog();
  AuditLog(const AuditLog&) = delete;
  AuditLog& operator=(const AuditLog&) = delete;
  // Records the entry and returns its sequence number.
  std::uint64_t record(AuditEntry entry);
  void finish(std::uint64_t seq, std::string outcome, std::string detail = {});
  // {"entries":[...]} newest first, at most `limit`.
  nlohmann::json to_json(std::size_t limit) const;
  std::uint64_t total() const;
  // Entries rotated out of memory so far.
  std::uint64_t dropped() const;
  // Startup: append every finished entry to `file` (created if missing). Throws std::runtime_error when it cannot.
  void persist_to(const std::filesystem::path& file);

 private:
  const std::size_t capacity_;
  std::uint64_t dropped_ = 0;
  std::mutex file_mutex_;  // the file's own lock: writing never holds mutex_
  std::FILE* file_ = nullptr;
  std::string file_name_;

  void append_line(const AuditEntry& entry) noexcept;
  mutable std::mutex mutex_;  // held for a copy or an assignment only; never around I/O or plugin calls
  std::deque<AuditEntry> entries_;
  std::uint64_t next_seq_ = 1;
};

}  // namespace rcand::kernel
