#include "kernel/safety/state_dir.hpp"

#include <fcntl.h>
#include <pthread.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <stdexcept>
#include <string_view>

#include "libs/base/bounded_text.hpp"
#include "libs/base/durable_file.hpp"
#include "libs/base/logging.hpp"
#include "libs/base/stop_path_priority.hpp"

namespace rcand::kernel {
namespace {

namespace fs = std::filesystem;

constexpr const char* kLatchFile = "estop.json";
constexpr const char* kSlotFile = "estop.slot";
constexpr const char* kRunningFile = "running";
constexpr const char* kLockFile = "lock";

[[noreturn]] void state_dir_error(const fs::path& dir, const std::string& what) {
  throw std::runtime_error("runtime.state_dir: " + dir.string() + ": " + what);
}

std::int64_t state_wall_ms() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::system_clock::now().time_since_epoch()).count();
}

}  // namespace

std::string StateDir::format(const LatchRecord& record, std::uint64_t seq) {
  nlohmann::json doc{{"latched", record.latched}, {"written_ms", state_wall_ms()}, {"seq", seq}};
  if (record.latched) {
    doc["reason"] = record.reason;
    doc["source"] = record.source;
    doc["since_ms"] = record.since_ms;
  }
  return doc.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace) + "\n";
}

std::optional<StateDir::LatchRecord> StateDir::parse(const std::string& text, std::uint64_t* seq) {
  const auto doc = nlohmann::json::parse(text, nullptr, false);
  if (!doc.is_object() || !doc.contains("latched") || !doc["latched"].is_boolean()) return std::nullopt;
  LatchRecord record;
  record.latched = doc["latched"].get<bool>();
  if (doc.contains("reason") && doc["reason"].is_string()) record.reason = doc["reason"].get<std::string>();
  if (doc.contains("source") && doc["source"].is_string()) record.source = doc["source"].get<std::string>();
  if (doc.contains("since_ms") && doc["since_ms"].is_number_integer()) record.since_ms = doc["since_ms"].get<std::int64_t>();
  if (seq != nullptr) *seq = doc.contains("seq") && doc["seq"].is_number_unsigned() ? doc["seq"].get<std::uint64_t>() : 0;
  return record;
}

StateDir::StateDir(fs::path dir) : dir_(std::move(dir)) {
  std::error_code ec;
  fs::create_directories(dir_, ec);
  if (ec) state_dir_error(dir_, "cannot create it: " + ec.message());
  if (!fs::is_directory(dir_, ec)) state_dir_error(dir_, "not a directory");
  take_lock(dir_ / kLockFile);
  try {
    read_previous();
  } catch (...) {
    ::close(lock_fd_);
    lock_fd_ = -1;
    throw;
  }
}

// The lock, and in the lock file who holds it: a second rcand is told which process to look at, whatever that one
// is doing yet (it takes the lock before it loads a plugin, and writes the running marker only once it serves).
void StateDir::take_lock(const fs::path& lock_file) {
  lock_fd_ = ::open(lock_file.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0640);
  if (lock_fd_ < 0) state_dir_error(dir_, std::string("cannot create ") + kLockFile + ": " + std::strerror(errno));
  if (::flock(lock_fd_, LOCK_EX | LOCK_NB) != 0) {
    const int error = errno;
    ::close(lock_fd_);
    lock_fd_ = -1;
    std::string holder = read_whole_file(lock_file).value_or("");
    while (!holder.empty() && (holder.back() == '\n' || holder.back() == '\r')) holder.pop_back();
    if (error == EWOULDBLOCK)
      state_dir_error(dir_, "in use by another rcand (" + bounded_text(holder.empty() ? "?" : holder) +
                                "); each rcand needs its own state dir, and one robot runs one rcand");
    state_dir_error(dir_, std::string("cannot lock it: ") + std::strerror(error));
  }
  const std::string holder = "pid " + std::to_string(::getpid()) + ", started " + std::to_string(state_wall_ms()) + " ms\n";
  if (::ftruncate(lock_fd_, 0) != 0 || ::pwrite(lock_fd_, holder.data(), holder.size(), 0) < 0)
    logger("kernel.state")
        ->warn("runtime.state_dir: cannot note this process in {}: {}", lock_file.string(), std::strerror(errno));
}

// The running marker, and the newest of the two latch records that parse (one that cannot be read may have said
// "latched": assume it did, unless the other one is readable).
void StateDir::read_previous() {
  if (const auto marker = read_whole_file(dir_ / kRunningFile)) {
    previous_.unclean_exit = true;
    previous_.marker = *marker;
    while (!previous_.marker.empty() && (previous_.marker.back() == '\n' || previous_.marker.back() == '\r'))
      previous_.marker.pop_back();
  }
  bool unreadable = false;
  for (const char* name : {kLatchFile, kSlotFile}) {
    const auto text = read_whole_file(dir_ / name);
    const bool blank = text && text->find_first_not_of(" \n") == std::string::npos;
    if (!text || (blank && std::string_view(name) == kSlotFile)) continue;  // none, or a slot reserved and never written
    std::uint64_t seq = 0;
    const auto record = parse(*text, &seq);
    if (!record) unreadable = true;
    else if (!previous_.latch || seq > seq_) previous_.latch = record, seq_ = seq;
  }
  if (!previous_.latch && unreadable)
    previous_.latch = LatchRecord{true, std::string("the e-stop record ") + kLatchFile + " is unreadable", "startup", 0};
}

void StateDir::mark_running() {
  // The slot's blocks are written now, while there is room: later rewrites in place need none.
  const fs::path slot = dir_ / kSlotFile;
  slot_fd_ = ::open(slot.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0640);
  struct stat info {};
  if (slot_fd_ < 0 || ::fstat(slot_fd_, &info) != 0)
    state_dir_error(dir_, "cannot open " + slot.string() + ": " + std::strerror(errno));
  if (info.st_size != static_cast<off_t>(kSlotBytes) || info.st_blocks * 512 < static_cast<blkcnt_t>(kSlotBytes)) {
    std::string text = read_whole_file(slot).value_or("");
    text.resize(kSlotBytes, ' ');
    if (::pwrite(slot_fd_, text.data(), text.size(), 0) != static_cast<ssize_t>(text.size()) || ::fsync(slot_fd_) != 0)
      state_dir_error(dir_, "cannot reserve " + slot.string() + ": " + std::strerror(errno));
  }
  const std::string marker = "pid " + std::to_string(::getpid()) + ", started " + std::to_string(state_wall_ms()) + " ms\n";
  if (const auto error = replace_file_durably(dir_, kRunningFile, marker); !error.empty()) state_dir_error(dir_, error);
}

StateDir::~StateDir() {
  stop_writer();
  if (slot_fd_ >= 0) ::close(slot_fd_);
  if (lock_fd_ >= 0) ::close(lock_fd_);
}

void StateDir::start_writer(std::function<LatchRecord()> current) {
  current_ = std::move(current);
  writer_ = std::thread([this] {
    pthread_setname_np(pthread_self(), "state.writer");
    enter_background_policy();  // its fsyncs follow every latch and clear; the stop's client comes first
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

// In place, in the space mark_running() wrote: no block to allocate, so no ENOSPC. A record cut by a crash in the
// middle does not parse; estop.json, written after the previous slot write, still holds the record before it.
// Returns an error text, empty when it worked.
std::string StateDir::write_slot(const std::string& text) noexcept {
  if (slot_fd_ < 0 || text.size() >= kSlotBytes) return "not reserved";
  std::string padded = text;
  padded.resize(kSlotBytes, ' ');
  if (::pwrite(slot_fd_, padded.data(), padded.size(), 0) != static_cast<ssize_t>(padded.size()) || ::fdatasync(slot_fd_) != 0)
    return std::strerror(errno);
  return {};
}

bool StateDir::write_latch(const LatchRecord& record) noexcept {
  try {
    ++seq_;
    LatchRecord bounded = record;  // the slot's copy: bounded so that it always fits (estop.json keeps it whole)
    bounded.reason = bounded_text(record.reason, 1024);
    bounded.source = bounded_text(record.source, 200);
    const auto slot_error = write_slot(format(bounded, seq_));
    const auto error = replace_file_durably(dir_, kLatchFile, format(record, seq_));
    auto log = logger("kernel.state");
    if (!slot_error.empty()) log->error("runtime.state_dir: cannot record the e-stop latch in {}: {}", kSlotFile, slot_error);
    if (!error.empty())
      log->error("runtime.state_dir: cannot record the e-stop latch: {}{}", error,
                 slot_error.empty() ? std::string("; it is kept in ") + kSlotFile : std::string());
    return slot_error.empty() || error.empty();
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
  if (ec || !fsync_directory(dir_))
    logger("kernel.state")
        ->error("runtime.state_dir: cannot remove the running marker in {}; the next start will be latched", dir_.string());
}

}  // namespace rcand::kernel
