#include "libs/base/rotating_file.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

namespace rcand {

RotatingFile::~RotatingFile() {
  if (fd_ >= 0) {
    ::fsync(fd_);
    ::close(fd_);
  }
}

std::filesystem::path RotatingFile::rotated_name(const std::filesystem::path& file, int index) {
  return file.string() + "." + std::to_string(index);
}

void RotatingFile::open(const std::filesystem::path& file, std::uintmax_t max_bytes, int keep, const std::string& setting) {
  const int fd = ::open(file.c_str(), O_RDWR | O_APPEND | O_CREAT | O_CLOEXEC, 0640);
  if (fd < 0) throw std::runtime_error(setting + ": cannot append to " + file.string() + ": " + std::strerror(errno));
  // One writer per file (one rcand per robot): a second one is refused before it writes a byte.
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    const int error = errno;
    ::close(fd);
    throw std::runtime_error(setting + ": " + file.string() +
                             (error == EWOULDBLOCK
                                  ? std::string(" is in use by another rcand; each robot keeps its own audit log")
                                  : ": cannot lock it: " + std::string(std::strerror(error))));
  }
  struct stat info {};
  std::uintmax_t size = ::fstat(fd, &info) == 0 ? static_cast<std::uintmax_t>(info.st_size) : 0;
  if (char last = '\n'; size > 0 && ::pread(fd, &last, 1, static_cast<off_t>(size - 1)) == 1 && last != '\n')
    if (::write(fd, "\n", 1) == 1) ++size;
  std::lock_guard lock(mutex_);
  if (fd_ >= 0) ::close(fd_);
  fd_ = fd;
  name_ = file.string();
  bytes_ = size;
  max_bytes_ = max_bytes;
  keep_ = keep < 1 ? 1 : keep;
  open_.store(true, std::memory_order_release);
}

int RotatingFile::rotate_locked() noexcept {
  // FILE.<keep> is dropped, FILE.<i> becomes FILE.<i+1>, FILE becomes FILE.1, and a new FILE is started. Renames
  // and an open only.
  const std::filesystem::path file = name_;
  std::error_code ec;
  std::filesystem::remove(rotated_name(file, keep_), ec);
  for (int i = keep_ - 1; i >= 1; --i) std::filesystem::rename(rotated_name(file, i), rotated_name(file, i + 1), ec);
  if (::rename(file.c_str(), rotated_name(file, 1).c_str()) != 0) return -1;
  const int fresh = ::open(file.c_str(), O_WRONLY | O_APPEND | O_CREAT | O_CLOEXEC, 0640);
  if (fresh < 0) return -1;           // keeps appending to the renamed file: nothing is lost
  ::flock(fresh, LOCK_EX | LOCK_NB);  // the new file is this rcand's too
  const int old = fd_;
  fd_ = fresh;
  bytes_ = 0;
  return old;
}

bool RotatingFile::append(std::string_view line) noexcept {
  int retired = -1;
  bool written_whole = false;
  {
    std::lock_guard lock(mutex_);
    if (fd_ < 0) return false;
    if (bytes_ > 0 && bytes_ + line.size() > max_bytes_) retired = rotate_locked();
    // One write per line, O_APPEND: a crash loses at most the line being written, never an earlier one.
    const ssize_t written = ::write(fd_, line.data(), line.size());
    if (written > 0) bytes_ += static_cast<std::uintmax_t>(written);
    written_whole = written == static_cast<ssize_t>(line.size());
  }
  if (retired >= 0) {
    ::fsync(retired);
    ::close(retired);
    try {
      const std::filesystem::path dir = std::filesystem::path(name_).parent_path();
      if (const int dir_fd = ::open(dir.empty() ? "." : dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC); dir_fd >= 0) {
        ::fsync(dir_fd);
        ::close(dir_fd);
      }
    } catch (...) {  // no memory for the directory's name: its entry is synced with the next rotation
    }
  }
  return written_whole;
}

std::vector<std::string> RotatingFile::tail_lines(const std::filesystem::path& file, std::size_t window) {
  std::vector<std::string> lines;
  const int fd = ::open(file.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return lines;
  struct stat info {};
  std::string tail;
  off_t from = 0;
  if (::fstat(fd, &info) == 0 && info.st_size > 0) {
    const off_t size = info.st_size;
    from = size > static_cast<off_t>(window) ? size - static_cast<off_t>(window) : 0;
    tail.resize(static_cast<std::size_t>(size - from));
    const ssize_t got = ::pread(fd, tail.data(), tail.size(), from);
    tail.resize(got > 0 ? static_cast<std::size_t>(got) : 0);
  }
  ::close(fd);
  std::size_t begin = 0;
  if (from > 0) {  // the window's first line is most likely cut: start after its end
    const auto first_end = tail.find('\n');
    begin = first_end == std::string::npos ? tail.size() : first_end + 1;
  }
  for (std::size_t end; (end = tail.find('\n', begin)) != std::string::npos; begin = end + 1)
    lines.emplace_back(tail, begin, end - begin);
  return lines;
}

}  // namespace rcand
