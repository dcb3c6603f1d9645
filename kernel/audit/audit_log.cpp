#include "kernel/audit/audit_log.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <optional>
#include <stdexcept>

#include "libs/base/bounded_text.hpp"

namespace rcand::kernel {
namespace {

nlohmann::json audit_entry_json(const AuditEntry& entry) {
  nlohmann::json item{{"seq", entry.seq},
                      {"principal", entry.principal},
                      {"ruri", entry.ruri},
                      {"timestamp_ms", entry.timestamp_ms},
                      {"message_id", entry.message_id},
                      {"event", entry.event},
                      {"outcome", entry.outcome}};
  if (!entry.detail.empty()) item["detail"] = entry.detail;
  if (entry.note.is_object())
    for (const auto& [key, value] : entry.note.items()) item.emplace(key, value);  // never over the entry's own
  return item;
}

std::int64_t audit_wall_ms() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::system_clock::now().time_since_epoch()).count();
}

std::filesystem::path rotated_name(const std::filesystem::path& file, int index) {
  return file.string() + "." + std::to_string(index);
}

// The highest "seq" among the complete lines at the end of `file` (its last 64 KiB), 0 when there is none.
std::uint64_t last_audit_seq(const std::filesystem::path& file) {
  const int fd = ::open(file.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return 0;
  struct stat info {};
  std::string tail;
  if (::fstat(fd, &info) == 0 && info.st_size > 0) {
    const off_t size = info.st_size;
    const off_t from = size > 65536 ? size - 65536 : 0;
    tail.resize(static_cast<std::size_t>(size - from));
    const ssize_t got = ::pread(fd, tail.data(), tail.size(), from);
    tail.resize(got > 0 ? static_cast<std::size_t>(got) : 0);
  }
  ::close(fd);
  // Every complete line of the tail (concurrent requests may write their lines slightly out of seq order; a last
  // line without its newline was cut by a crash and is skipped, as is a first one cut by the 64 KiB window).
  std::uint64_t best = 0;
  std::size_t begin = 0;
  for (std::size_t end; (end = tail.find('\n', begin)) != std::string::npos; begin = end + 1) {
    const auto line = nlohmann::json::parse(tail.begin() + static_cast<std::ptrdiff_t>(begin),
                                            tail.begin() + static_cast<std::ptrdiff_t>(end), nullptr, false);
    if (line.is_object() && line.contains("seq") && line["seq"].is_number_unsigned())
      best = std::max(best, line["seq"].get<std::uint64_t>());
  }
  return best;
}

}  // namespace

bool AuditLog::log_line_allowed(const std::string& principal) noexcept {
  try {
    const auto verdict = log_limit_.admit(principal);
    if (verdict.log && verdict.suppressed > 0)
      logger("kernel.audit")
          ->warn("{} audit log lines for {} suppressed (more than {} a second; the audit log itself has them all)",
                 verdict.suppressed, principal, kLogLinesPerSecond);
    return verdict.log;
  } catch (...) {
    return false;
  }
}

void AuditLog::identify(std::string robot_ruri, const sdk::Clock& clock) {
  robot_ruri_ = std::move(robot_ruri);
  clock_ = &clock;
}

std::uint64_t AuditLog::begin(const std::string& principal, const std::string& message_id, std::string event,
                              nlohmann::json note) {
  const std::int64_t now_ms =
      clock_ != nullptr
          ? clock_->wall_ms()
          : std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::system_clock::now().time_since_epoch()).count();
  return record({0, principal, robot_ruri_, message_id, std::move(event), now_ms, "pending", {}, std::move(note)});
}

std::uint64_t AuditLog::record(AuditEntry entry) {
  // Every field may carry what a client sent (a message id, an action type, a path): bounded before it is kept.
  entry.principal = bounded_text(entry.principal, kFieldLimit);
  entry.ruri = bounded_text(entry.ruri, kFieldLimit);
  entry.message_id = bounded_text(entry.message_id, kFieldLimit);
  entry.event = bounded_text(entry.event, kEventLimit);
  entry.outcome = bounded_text(entry.outcome, kFieldLimit);
  entry.detail = bounded_text(entry.detail, kDetailLimit);
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
  if (persisting_.load(std::memory_order_acquire)) {
    auto line = audit_entry_json(entry);
    line["kind"] = "entry";
    append_line(seq, line);  // before dispatch: a crash while the command runs leaves this pending line
  }
  if (log_line_allowed(entry.principal))
    logger("kernel.audit")->info("#{} {} by {} ({})", seq, entry.event, entry.principal, entry.message_id);
  return seq;
}

void AuditLog::finish(std::uint64_t seq, std::string outcome, std::string detail) {
  outcome = bounded_text(outcome, kFieldLimit);
  detail = bounded_text(detail, kDetailLimit);
  std::optional<AuditEntry> finished;
  {
    std::lock_guard lock(mutex_);
    if (!entries_.empty() && seq >= entries_.front().seq && seq <= entries_.back().seq) {
      auto& entry = entries_[seq - entries_.front().seq];
      entry.outcome = outcome;
      entry.detail = detail;
      finished = entry;
    }
  }
  if (persisting_.load(std::memory_order_acquire)) {
    nlohmann::json line;
    if (finished) {
      line = audit_entry_json(*finished);
    } else {  // already rotated out of memory: the outcome alone, under the same seq
      line = {{"seq", seq}, {"outcome", outcome}};
      if (!detail.empty()) line["detail"] = detail;
    }
    line["kind"] = "outcome";
    line["finished_ms"] = audit_wall_ms();
    append_line(seq, line);
  }
  if (log_line_allowed(finished ? finished->principal : std::string("?")))
    logger("kernel.audit")->info("#{} {}{}{}", seq, outcome, detail.empty() ? "" : ": ", detail);
}

AuditLog::~AuditLog() {
  if (fd_ >= 0) {
    ::fsync(fd_);
    ::close(fd_);
  }
}

void AuditLog::persist_to(const std::filesystem::path& file, std::uintmax_t max_bytes, int keep) {
  const int fd = ::open(file.c_str(), O_RDWR | O_APPEND | O_CREAT | O_CLOEXEC, 0640);
  if (fd < 0) throw std::runtime_error("runtime.audit_file: cannot append to " + file.string() + ": " + std::strerror(errno));
  // One rcand per audit file (one per robot): a second one is refused before it writes a byte.
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    const int error = errno;
    ::close(fd);
    throw std::runtime_error("runtime.audit_file: " + file.string() +
                             (error == EWOULDBLOCK
                                  ? std::string(" is in use by another rcand; each robot keeps its own audit log")
                                  : ": cannot lock it: " + std::string(std::strerror(error))));
  }
  struct stat info {};
  std::uintmax_t size = ::fstat(fd, &info) == 0 ? static_cast<std::uintmax_t>(info.st_size) : 0;
  // A last line cut by a crash gets its newline, so the next entry starts a line of its own.
  if (char last = '\n'; size > 0 && ::pread(fd, &last, 1, static_cast<off_t>(size - 1)) == 1 && last != '\n')
    if (::write(fd, "\n", 1) == 1) ++size;
  // Continue the sequence: from this file, or from the last rotated one when this one was just started.
  std::uint64_t last = last_audit_seq(file);
  if (last == 0) last = last_audit_seq(rotated_name(file, 1));
  {
    std::lock_guard lock(mutex_);
    if (entries_.empty() && last >= next_seq_) next_seq_ = first_seq_ = last + 1;
  }
  std::lock_guard file_lock(file_mutex_);
  if (fd_ >= 0) ::close(fd_);
  fd_ = fd;
  file_name_ = file.string();
  file_bytes_ = size;
  max_bytes_ = max_bytes;
  keep_ = keep < 1 ? 1 : keep;
  persisting_.store(true, std::memory_order_release);
}

int AuditLog::rotate_locked() noexcept {
  // FILE.<keep> is dropped, FILE.<i> becomes FILE.<i+1>, FILE becomes FILE.1, and a new FILE is started. Renames
  // and an open only: the old descriptor is fsync'd and closed by the caller outside the lock.
  const std::filesystem::path file = file_name_;
  std::error_code ec;
  std::filesystem::remove(rotated_name(file, keep_), ec);
  for (int i = keep_ - 1; i >= 1; --i) std::filesystem::rename(rotated_name(file, i), rotated_name(file, i + 1), ec);
  if (::rename(file.c_str(), rotated_name(file, 1).c_str()) != 0) return -1;
  const int fresh = ::open(file.c_str(), O_WRONLY | O_APPEND | O_CREAT | O_CLOEXEC, 0640);
  if (fresh < 0) return -1;           // keeps appending to the renamed file: nothing is lost
  ::flock(fresh, LOCK_EX | LOCK_NB);  // the new file is this rcand's too
  const int old = fd_;
  fd_ = fresh;
  file_bytes_ = 0;
  return old;
}

void AuditLog::append_line(std::uint64_t seq, const nlohmann::json& line_json) noexcept {
  try {
    const std::string line = line_json.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace) + "\n";
    int retired = -1;
    bool failed = false;
    {
      std::lock_guard lock(file_mutex_);
      if (fd_ < 0) return;
      if (file_bytes_ > 0 && file_bytes_ + line.size() > max_bytes_) retired = rotate_locked();
      // One write per line, O_APPEND: a crash loses at most the line being written, never an earlier one.
      const ssize_t written = ::write(fd_, line.data(), line.size());
      if (written > 0) file_bytes_ += static_cast<std::uintmax_t>(written);
      failed = written != static_cast<ssize_t>(line.size());
    }
    if (retired >= 0) {
      ::fsync(retired);
      ::close(retired);
      const std::filesystem::path dir = std::filesystem::path(file_name_).parent_path();
      if (const int dir_fd = ::open(dir.empty() ? "." : dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC); dir_fd >= 0) {
        ::fsync(dir_fd);
        ::close(dir_fd);
      }
    }
    if (failed) logger("kernel.audit")->error("cannot write audit entry #{} to {}", seq, file_name_);
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
  for (auto it = entries_.rbegin(); it != entries_.rend() && list.size() < limit; ++it) list.push_back(audit_entry_json(*it));
  nlohmann::json doc{{"entries", std::move(list)}, {"total", next_seq_ - first_seq_}, {"dropped", dropped_}};
  if (persisting_.load(std::memory_order_acquire)) doc["file"] = file_name_;
  return doc;
}

std::uint64_t AuditLog::total() const {
  std::lock_guard lock(mutex_);
  return next_seq_ - first_seq_;
}

}  // namespace rcand::kernel
