#include "kernel/safety/state_dir.hpp"

#include <fcntl.h>
#include <pthread.h>
#include <sys/file.h>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "libs/base/logging.hpp"

namespace rcand::kernel {
namespace {

namespace fs = std::filesystem;

constexpr const char* kLatchFile = "estop.json";
constexpr const char* kRunningFile = "running";
constexpr const char* kLockFile = "lock";

[[noreturn]] void state_dir_error(const fs::path& dir, const std::string& what) {
  throw std::runtime_error("runtime.state_dir: " + dir.string() + ": " + what);
}

std::optional<std::string> read_state_file(const fs::path& file) {
  std::error_code ec;
  if (!fs::exists(file, ec)) return std::nullopt;
  std::ifstream in(file, std::ios::binary);
  if (!in) return std::string();
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

bool fsync_state_dir(const fs::path& dir) {
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return false;
  const bool ok = ::fsync(fd) == 0;
  ::close(fd);
  return ok;
}

// Temp file, write, fsync, rename over `name`, fsync the directory: after a crash the file is the old or the new
// one, whole. Returns an error text, empty when it worked.
std::string write_state_file(const fs::path& dir, const std::string& name, const std::string& text) {
  const fs::path final_path = dir / name;
  const fs::path temp = dir / (name + ".tmp");
  const int fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0640);
  if (fd < 0) return "cannot create " + temp.string() + ": " + std::strerror(errno);
  std::size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = ::write(fd, text.data() + done, text.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const std::string error = std::strerror(errno);
      ::close(fd);
      return "cannot write " + temp.string() + ": " + error;
    }
    done += static_cast<std::size_t>(n);
  }
  if (::fsync(fd) != 0) {
    const std::string error = std::strerror(errno);
    ::close(fd);
    return "cannot fsync " + temp.string() + ": " + error;
  }
  ::close(fd);
  if (::rename(temp.c_str(), final_path.c_str()) != 0)
    return "cannot rename to " + final_path.string() + ": " + std::strerror(errno);
  if (!fsync_state_dir(dir)) return "cannot fsync " + dir.string();
  return {};
}

std::int64_t state_wall_ms() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::system_clock::now().time_since_epoch()).count();
}

}  // namespace

std::string StateDir::format(const LatchRecord& record) {
  nlohmann::json doc{{"latched", record.latched}, {"written_ms", state_wall_ms()}};
  if (record.latched) {
    doc["reason"] = record.reason;
    doc["source"] = record.source;
    doc["since_ms"] = record.since_ms;
  }
  return doc.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace) + "\n";
}

std::optional<StateDir::LatchRecord> StateDir::parse(const std::string& text) {
  const auto doc = nlohmann::json::parse(text, nullptr, false);
  if (!doc.is_object() || !doc.contains("latched") || !doc["latched"].is_boolean()) return std::nullopt;
  LatchRecord record;
  record.latched = doc["latched"].get<bool>();
  if (doc.contains("reason") && doc["reason"].is_string()) record.reason = doc["reason"].get<std::string>();
  if (doc.contains("source") && doc["source"].is_string()) record.source = doc["source"].get<std::string>();
  if (doc.contains("since_ms") && doc["since_ms"].is_number_integer()) record.since_ms = doc["since_ms"].get<std::int64_t>();
  return record;
}

StateDir::StateDir(fs::path dir) : dir_(std::move(dir)) {
  std::error_code ec;
  fs::create_directories(dir_, ec);
  if (ec) state_dir_error(dir_, "cannot create it: " + ec.message());
  if (!fs::is_directory(dir_, ec)) state_dir_error(dir_, "not a directory");
  const fs::path lock_file = dir_ / kLockFile;
  lock_fd_ = ::open(lock_file.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0640);
  if (lock_fd_ < 0) state_dir_error(dir_, std::string("cannot create ") + kLockFile + ": " + std::strerror(errno));
  if (::flock(lock_fd_, LOCK_EX | LOCK_NB) != 0) {
    const int error = errno;
    ::close(lock_fd_);
    lock_fd_ = -1;
    if (error == EWOULDBLOCK)
      state_dir_error(dir_, "in use by another rcand (" + read_state_file(dir_ / kRunningFile).value_or("?") +
                                "); each rcand needs its own state dir");
    state_dir_error(dir_, std::string("cannot lock it: ") + std::strerror(error));
  }
  try {
    if (const auto marker = read_state_file(dir_ / kRunningFile)) {
      previous_.unclean_exit = true;
      previous_.marker = *marker;
      while (!previous_.marker.empty() && (previous_.marker.back() == '\n' || previous_.marker.back() == '\r'))
        previous_.marker.pop_back();
    }
    if (const auto text = read_state_file(dir_ / kLatchFile)) {
      previous_.latch = parse(*text);
      // A record that cannot be read may have said "latched": assume it did.
      if (!previous_.latch)
        previous_.latch = LatchRecord{true, std::string("the e-stop record ") + kLatchFile + " is unreadable", "startup", 0};
    }
    const std::string marker = "pid " + std::to_string(::getpid()) + ", started " + std::to_string(state_wall_ms()) + " ms\n";
    if (const auto error = write_state_file(dir_, kRunningFile, marker); !error.empty()) state_dir_error(dir_, error);
  } catch (...) {
    ::close(lock_fd_);
    lock_fd_ = -1;
    throw;
  }
}

StateDir::~StateDir() {
  stop_writer();
  if (lock_fd_ >= 0) ::close(lock_fd_);
}

void StateDir::start_writer(std::function<LatchRecord()> current) {
  current_ = std::move(current);
  writer_ = std::thread([this] {
    pthread_setname_np(pthread_self(), "state.writer");
    std::unique_lock lock(mutex_);
    for (;;) {
      wake_.wait(lock, [this] { return dirty_ || stopping_; });
      if (!dirty_) return;  // stopping, with nothing left to write (a change still pending is written first)
      dirty_ = false;
      lock.unlock();
      try {
        write_latch(current_());
      } catch (...) {  // the record is best effort on top of the running marker, which already covers a crash
      }
      lock.lock();
    }
  });
}

void StateDir::latch_changed() noexcept {
  {
    std::lock_guard lock(mutex_);
    dirty_ = true;
  }
  wake_.notify_one();
}

void StateDir::stop_writer() noexcept {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_one();
  if (writer_.joinable()) writer_.join();
}

bool StateDir::write_latch(const LatchRecord& record) noexcept {
  try {
    const auto error = write_state_file(dir_, kLatchFile, format(record));
    if (error.empty()) return true;
    logger("kernel.state")->error("runtime.state_dir: cannot record the e-stop latch: {}", error);
  } catch (...) {
  }
  return false;
}

void StateDir::clean_exit(const LatchRecord& last) noexcept {
  stop_writer();
  // Without the record, the marker is what makes the next start latched: it stays.
  if (!write_latch(last)) return;
  std::error_code ec;
  fs::remove(dir_ / kRunningFile, ec);
  if (ec || !fsync_state_dir(dir_))
    logger("kernel.state")
        ->error("runtime.state_dir: cannot remove the running marker in {}; the next start will be latched", dir_.string());
}

}  // namespace rcand::kernel
