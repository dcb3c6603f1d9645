// Bulk bytes from an isolated capability's host to rcand (issue 34: a camera's frames through shared memory). rcand
// makes the ring, a sealed memfd (it can neither shrink nor grow, so a host cannot make rcand's reads fault), and maps
// only its header page, read-only; the host maps the whole file writable (descriptor 4) and writes each frame once,
// contiguously, at the next absolute position. Only the frame's place and length cross the channel; rcand copies a
// frame out with one pread() (so the ring's pages never count in rcand's resident memory), once however many viewers
// it is pushed to.
//
// The host may lap a reader that is slow to take a frame: the header's `reserved` is the end of the newest frame
// begun, stored before its bytes are written (a seqlock: the writer's release fence, the reader's acquire fence). A
// reader copies the frame, then checks that nothing was begun past its place plus the ring's size; a frame written
// over meanwhile is refused, and counts as dropped. A host is not trusted: every place and length is checked against
// the mapping rcand made.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "rcand/sdk/stream.hpp"

namespace rcand::isolation {

// A frame's place in the ring: absolute byte positions, never reused.
struct RingSlot {
  std::uint64_t at = 0;
  std::uint32_t length = 0;
};

class FrameRing {
 public:
  static constexpr std::size_t kDefaultBytes = 4u << 20;

  // rcand's side: a new sealed memfd of `bytes`, its header mapped read-only. Throws std::system_error.
  static std::unique_ptr<FrameRing> create(std::size_t bytes = kDefaultBytes);
  // The host's side: the ring rcand passed as `fd` (taken), mapped writable. Throws std::system_error.
  static std::unique_ptr<FrameRing> attach(int fd);
  ~FrameRing();
  FrameRing(const FrameRing&) = delete;
  FrameRing& operator=(const FrameRing&) = delete;

  int fd() const noexcept { return fd_; }
  // The largest frame the ring carries (half its data): a bigger one goes inline in its message.
  std::size_t max_frame() const noexcept { return data_bytes_ / 2; }

  // The host: `bytes` written once, its slot returned; the same bytes again (one frame pushed to many viewers) reuse
  // the slot while it is intact. nullopt: over max_frame(). Any thread.
  std::optional<RingSlot> put(const sdk::SharedBytes& bytes);

  // rcand: the frame at `slot`, copied once, and shared by every later take of the same slot while it is remembered.
  // null: a place or length outside the ring, or the frame was written over before it was read. Any thread.
  sdk::SharedBytes take(const RingSlot& slot);

 private:
  FrameRing(int fd, unsigned char* base, std::size_t bytes, bool writable);
  std::uint64_t& reserved() const noexcept;
  unsigned char* data() const noexcept;
  bool intact(const RingSlot& slot) const noexcept;

  int fd_;
  unsigned char* base_;
  std::size_t bytes_, data_bytes_;
  bool writable_;
  std::mutex mutex_;  // the writer's position and its recent frames
  std::uint64_t next_ = 0;
  struct Recent {
    sdk::SharedBytes bytes;
    RingSlot slot;
  };
  std::vector<Recent> recent_;  // the host's last frames (put), or rcand's last copies (take)
};

}  // namespace rcand::isolation
