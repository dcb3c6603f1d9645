#include "rcand/kernel/core/audit_log.hpp"

#include <optional>
#include <stdexcept>

#include "rcand/kernel/core/logging.hpp"

namespace rcand::kernel {
namespace {

nlohmann::json entry_json(const AuditEntry& entry) {
  nlohmann::json item{{"seq", entry.seq},           {"principal", entry.principal}, {"ruri", entry.ruri},
                      {"timestamp_ms", entry.timestamp_ms}, {"message_id", entry.message_id}, {"event", entry.event},
                      {"outcome", entry.outcome}};
  if (!entry.detail.empty()) item["detail"] = entry.detail;
  return item;
}

}  // namespace

std::uint64_t AuditLog::record(AuditEntry entry) {
  std::uint64_t seq;
  {
    std::lock_guard lock(mutex_);
    seq = entry.seq = next_seq_++;
    if (entries_.size() == capacity_) {
      entries_.pop_front();
      ++dropped_;
    }
    entries_.push_back(entry);
  }
  logger("kernel.audit")->info("#{} {} by {} ({})", seq, entry.event, entry.principal, entry.message_id);
  return seq;
}

void AuditLog::finish(std::uint64_t seq, std::string outcome, std::string detail) {
  std::optional<AuditEntry> finished;
  {
    std::lock_guard lock(mutex_);
    if (entries_.empty() || seq < entries_.front().seq || seq > entries_.back().seq) return;  // already rotated out
    auto& entry = entries_[seq - entries_.front().seq];
    entry.outcome = outcome;
    entry.detail = detail;
    if (file_ != nullptr) finished = entry;
  }
  if (finished) append_line(*finished);
  logger("kernel.audit")->info("#{} {}{}{}", seq, outcome, detail.empty() ? "" : ": ", detail);
}

AuditLog::~AuditLog() {
  if (file_ != nullptr) std::fclose(file_);
}

void AuditLog::persist_to(const std::filesystem::path& file) {
  std::FILE* opened = std::fopen(file.c_str(), "a");
  if (opened == nullptr) throw std::runtime_error("runtime.audit_file: cannot append to " + file.string());
  std::lock_guard lock(mutex_);
  file_ = opened;
  file_name_ = file.string();
}

void AuditLog::append_line(const AuditEntry& entry) noexcept {
  try {
    const std::string line = entry_json(entry).dump(-1, ' ', false, nlohmann::json::error_handler_t::replace) + "\n";
    std::lock_guard lock(file_mutex_);
    // One write per line: a crash loses at most the line being written, never an earlier one.
    if (std::fwrite(line.data(), 1, line.size(), file_) != line.size() || std::fflush(file_) != 0)
      logger("kernel.audit")->error("cannot write audit entry #{} to {}", entry.seq, file_name_);
  } catch (...) {
  }
}

std::uint64_t AuditLog::dropped() const {
  std::lock_guard lock(mutex_);
  return dropped_;
}

nlohmann::json AuditLog::to_json(std::size_t limit) const {
  nlohmann::json list = nlohmann::json::array();
  std::lock_guard lock(mutex_);
  for (auto it = entries_.rbegin(); it != entries_.rend() && list.size() < limit; ++it) list.push_back(entry_json(*it));
  nlohmann::json doc{{"entries", std::move(list)}, {"total", next_seq_ - 1}, {"dropped", dropped_}};
  if (file_ != nullptr) doc["file"] = file_name_;
  return doc;
}

std::uint64_t AuditLog::total() const {
  std::lock_guard lock(mutex_);
  return next_seq_ - 1;
}

}  // namespace rcand::kernel
