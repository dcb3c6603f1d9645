// The audit log (notes §6.3): every command and config change is recorded BEFORE dispatch, then its outcome
// (ok | blocked | error) is filled in. Bounded in memory; every entry is also written to the "kernel.audit" log.
#pragma once

#include <nlohmann/json.hpp>

#include <cstdint>
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
  // Records the entry and returns its sequence number.
  std::uint64_t record(AuditEntry entry);
  void finish(std::uint64_t seq, std::string outcome, std::string detail = {});
  // {"entries":[...]} newest first, at most `limit`.
  nlohmann::json to_json(std::size_t limit) const;
  std::uint64_t total() const;

 private:
  const std::size_t capacity_;
  mutable std::mutex mutex_;  // held for a copy or an assignment only; never around I/O or plugin calls
  std::deque<AuditEntry> entries_;
  std::uint64_t next_seq_ = 1;
};

}  // namespace rcand::kernel
