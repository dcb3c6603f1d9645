#include "libs/isolation/frame_ring.hpp"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstring>
#include <system_error>

namespace rcand::isolation {

namespace {

constexpr std::size_t kHeader = 4096;  // `reserved`, on a page of its own: all that rcand maps
constexpr std::size_t kRecent = 8;

[[noreturn]] void fail(const char* what) { throw std::system_error(errno, std::generic_category(), what); }

}  // namespace

std::unique_ptr<FrameRing> FrameRing::create(std::size_t bytes) {
  const int fd = ::memfd_create("rcand-frames", MFD_CLOEXEC | MFD_ALLOW_SEALING);
  if (fd < 0) fail("memfd_create");
  if (::ftruncate(fd, static_cast<off_t>(bytes)) != 0 ||
      ::fcntl(fd, F_ADD_SEALS, F_SEAL_SHRINK | F_SEAL_GROW | F_SEAL_SEAL) != 0) {
    const int error = errno;
    ::close(fd);
    errno = error;
    fail("sealing the frame ring");
  }
  void* base = bytes > kHeader ? ::mmap(nullptr, kHeader, PROT_READ, MAP_SHARED, fd, 0) : MAP_FAILED;
  if (base == MAP_FAILED) {
    const int error = errno;
    ::close(fd);
    errno = error;
    fail("mapping the frame ring");
  }
  return std::unique_ptr<FrameRing>(new FrameRing(fd, static_cast<unsigned char*>(base), bytes, false));
}

std::unique_ptr<FrameRing> FrameRing::attach(int fd) {
  struct stat info {};
  if (::fstat(fd, &info) != 0) fail("the frame ring");
  const auto bytes = static_cast<std::size_t>(info.st_size);
  if (bytes <= kHeader) {
    ::close(fd);
    errno = EINVAL;
    fail("the frame ring is too small");
  }
  void* base = ::mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
  if (base == MAP_FAILED) fail("mapping the frame ring");
  return std::unique_ptr<FrameRing>(new FrameRing(fd, static_cast<unsigned char*>(base), bytes, true));
}

FrameRing::FrameRing(int fd, unsigned char* base, std::size_t bytes, bool writable)
    : fd_(fd), base_(base), bytes_(bytes), data_bytes_(bytes - kHeader), writable_(writable) {}

FrameRing::~FrameRing() {
  ::munmap(base_, writable_ ? bytes_ : kHeader);
  ::close(fd_);
}

std::uint64_t& FrameRing::reserved() const noexcept { return *reinterpret_cast<std::uint64_t*>(base_); }
unsigned char* FrameRing::data() const noexcept { return base_ + kHeader; }

// Written (begun before now), and nothing begun past the slot's place plus the ring's size: its bytes are as they were
// written.
bool FrameRing::intact(const RingSlot& slot) const noexcept {
  std::atomic_thread_fence(std::memory_order_acquire);
  const std::uint64_t newest = std::atomic_ref<std::uint64_t>(reserved()).load(std::memory_order_relaxed);
  return slot.at + slot.length <= newest && newest <= slot.at + data_bytes_;
}

std::optional<RingSlot> FrameRing::put(const sdk::SharedBytes& bytes) {
  if (!writable_ || !bytes || bytes->size() > max_frame()) return std::nullopt;
  std::lock_guard lock(mutex_);
  for (const auto& recent : recent_)
    if (recent.bytes == bytes && next_ <= recent.slot.at + data_bytes_) return recent.slot;
  RingSlot slot{next_, static_cast<std::uint32_t>(bytes->size())};
  if (slot.at % data_bytes_ + slot.length > data_bytes_) slot.at += data_bytes_ - slot.at % data_bytes_;  // contiguous
  next_ = slot.at + slot.length;
  std::atomic_ref<std::uint64_t>(reserved()).store(next_, std::memory_order_relaxed);
  std::atomic_thread_fence(std::memory_order_release);  // `reserved` is seen before any of the bytes below
  std::memcpy(data() + slot.at % data_bytes_, bytes->data(), slot.length);
  if (recent_.size() == kRecent) recent_.erase(recent_.begin());
  recent_.push_back({bytes, slot});
  return slot;
}

sdk::SharedBytes FrameRing::take(const RingSlot& slot) {
  if (slot.length > max_frame() || slot.at % data_bytes_ + slot.length > data_bytes_) return nullptr;
  std::lock_guard lock(mutex_);
  for (const auto& recent : recent_)
    if (recent.slot.at == slot.at && recent.slot.length == slot.length) return recent.bytes;
  auto copy = std::make_shared<std::string>(slot.length, '\0');
  const auto offset = static_cast<off_t>(kHeader + slot.at % data_bytes_);
  if (::pread(fd_, copy->data(), slot.length, offset) != static_cast<ssize_t>(slot.length) || !intact(slot)) return nullptr;
  if (recent_.size() == kRecent) recent_.erase(recent_.begin());
  recent_.push_back({copy, slot});
  return copy;
}

}  // namespace rcand::isolation
