// An append-only file of lines that rotates by size: FILE -> FILE.1 -> ... -> FILE.<keep>, then a new FILE. Each
// line is one write(2) on an O_APPEND descriptor, so a crash (kill -9, abort) loses no line already appended; lines
// are not fsync'd one by one (a power loss may lose the last ones), a file is fsync'd when rotated out and when
// closed. Any thread: one short lock around the write (and, when a file is full, the renames); the fsync and close
// of a rotated descriptor happen outside it. Used by the audit log (kernel/audit/audit_log.hpp).
#pragma once

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

namespace rcand {

class RotatingFile {
 public:
  RotatingFile() = default;
  ~RotatingFile();  // fsync and close
  RotatingFile(const RotatingFile&) = delete;
  RotatingFile& operator=(const RotatingFile&) = delete;

  // Startup: appends to `file` (created if missing, mode 0640); a last line cut by a crash gets its newline, so the
  // next line starts a line of its own; the file is flock'ed (one writer). Throws std::runtime_error naming `setting`
  // when it cannot, or when another process holds it.
  void open(const std::filesystem::path& file, std::uintmax_t max_bytes, int keep, const std::string& setting);
  bool is_open() const noexcept { return open_.load(std::memory_order_acquire); }
  // The file's name (stable once is_open()).
  const std::string& name() const noexcept { return name_; }
  // Appends `line` (ending in '\n'), rotating first when it would take the file past max_bytes. False when it was
  // not written whole (or nothing is open). Never throws.
  bool append(std::string_view line) noexcept;

  static std::filesystem::path rotated_name(const std::filesystem::path& file, int index);
  // The complete lines in the last `window` bytes of `file` (a first line cut by the window and a last one cut by a
  // crash are left out); empty when it cannot be read.
  static std::vector<std::string> tail_lines(const std::filesystem::path& file, std::size_t window = 65536);

 private:
  std::mutex mutex_;
  int fd_ = -1;  // under mutex_
  std::uintmax_t bytes_ = 0, max_bytes_ = 0;
  int keep_ = 1;
  std::string name_;
  std::atomic<bool> open_{false};

  int rotate_locked() noexcept;  // returns the old descriptor, to be fsync'd and closed outside the lock
};

}  // namespace rcand
