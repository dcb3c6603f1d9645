#include "rcand/kernel/core/audit_log.hpp"

#include "rcand/kernel/core/logging.hpp"

namespace rcand::kernel {

std::uint64_t AuditLog::record(AuditEntry entry) {
  std::uint64_t seq;
  {
    std::lock_guard lock(mutex_);
    seq = entry.seq = next_seq_++;
    if (entries_.size() == capacity_) entries_.pop_front();
    entries_.push_back(entry);
  }
  logger("kernel.audit")->info("#{} {} by {} ({})", seq, entry.event, entry.principal, entry.message_id);
  return seq;
}

void AuditLog::finish(std::uint64_t seq, std::string outcome, std::string detail) {
  {
    std::lock_guard lock(mutex_);
    if (entries_.empty() || seq < entries_.front().seq || seq > entries_.back().seq) return;  // already rotated out
    auto& entry = entries_[seq - entries_.front().seq];
    entry.outcome = outcome;
    entry.detail = detail;
  }
  logger("kernel.audit")->info("#{} {}{}{}", seq, outcome, detail.empty() ? "" : ": ", detail);
}

nlohmann::json AuditLog::to_json(std::size_t limit) const {
  nlohmann::json list = nlohmann::json::array();
  std::lock_guard lock(mutex_);
  for (auto it = entries_.rbegin(); it != entries_.rend() && list.size() < limit; ++it) {
    nlohmann::json item{{"seq", it->seq},           {"principal", it->principal}, {"ruri", it->ruri},
                        {"timestamp_ms", it->timestamp_ms}, {"message_id", it->message_id}, {"event", it->event},
                        {"outcome", it->outcome}};
    if (!it->detail.empty()) item["detail"] = it->detail;
    list.push_back(std::move(item));
  }
  return {{"entries", std::move(list)}};
}

std::uint64_t AuditLog::total() const {
  std::lock_guard lock(mutex_);
  return next_seq_ - 1;
}

}  // namespace rcand::kernel
