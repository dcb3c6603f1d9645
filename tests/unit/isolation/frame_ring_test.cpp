#include "libs/isolation/frame_ring.hpp"

#include <doctest/doctest.h>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <string>

using rcand::isolation::FrameRing;
using rcand::isolation::RingSlot;

namespace {

rcand::sdk::SharedBytes bytes(std::size_t size, char fill) { return std::make_shared<const std::string>(size, fill); }

// rcand's ring and the host's view of the same file, as rcand-plugin-host gets it (descriptor passed, mapped there).
struct Rings {
  std::unique_ptr<FrameRing> rcand = FrameRing::create(64 * 1024);
  std::unique_ptr<FrameRing> host = FrameRing::attach(::fcntl(rcand->fd(), F_DUPFD_CLOEXEC, 0));
};

}  // namespace

TEST_CASE("frame ring: a frame written once by the host is read whole by rcand, once however often it is taken") {
  Rings rings;
  const auto frame = bytes(10000, 'a');
  const auto slot = rings.host->put(frame);
  REQUIRE(slot);
  CHECK(rings.host->put(frame)->at == slot->at);  // pushed to a second viewer: the same slot, not written again
  const auto taken = rings.rcand->take(*slot);
  REQUIRE(taken);
  CHECK(*taken == *frame);
  CHECK(rings.rcand->take(*slot) == taken);  // the second viewer shares rcand's one copy
  const auto other = rings.host->put(bytes(10000, 'b'));
  REQUIRE(other);
  CHECK(other->at == slot->at + 10000);
  CHECK(*rings.rcand->take(*other) == std::string(10000, 'b'));
}

TEST_CASE("frame ring: a frame stays contiguous across the end; one written over before rcand read it is refused") {
  Rings rings;
  const std::size_t frame = rings.host->max_frame() / 2 + 1;  // three fit in the ring; the fourth starts it again
  std::vector<RingSlot> slots;
  for (char fill = 'a'; fill < 'a' + 5; ++fill) slots.push_back(*rings.host->put(bytes(frame, fill)));
  // The newest frame reads whole; the first one was written over.
  CHECK(*rings.rcand->take(slots.back()) == std::string(frame, 'e'));
  CHECK_FALSE(rings.rcand->take(slots.front()));
  for (const auto& slot : slots) CHECK(slot.at % (rings.host->max_frame() * 2) + slot.length <= rings.host->max_frame() * 2);
}

TEST_CASE("frame ring: an untrusted slot outside the ring reaches nothing, and the host cannot shrink the file") {
  Rings rings;
  CHECK_FALSE(rings.rcand->take({0, static_cast<std::uint32_t>(rings.rcand->max_frame() + 1)}));
  CHECK_FALSE(rings.rcand->take({rings.rcand->max_frame() * 2 - 10, 100}));  // past the end of the data
  CHECK_FALSE(rings.rcand->take({1u << 30, 100}));                           // a place not written yet
  CHECK_FALSE(rings.host->put(bytes(rings.host->max_frame() + 1, 'x')));     // too big: the caller sends it inline
  CHECK(::ftruncate(rings.host->fd(), 0) != 0);                              // sealed: a read by rcand can never fault
  CHECK(::ftruncate(rings.host->fd(), 1 << 30) != 0);
}
