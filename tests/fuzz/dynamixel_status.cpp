// libFuzzer target: what Dynamixel servos send back, through the plugin's own Protocol 2.0 code
// (plugins/dynamixel/packet.cpp, dxl_bus.cpp). The first byte picks one transaction of DxlBus (ping, broadcast scan,
// read, write, reboot, sync read) with parameters from the input's tail; the rest is the serial line's bytes as they
// arrive, cut into chunks of fuzzer-chosen sizes. Invariants:
//  - the stream decoder returns the same packets whether the bytes come at once or in chunks, and every packet it
//    returns encodes to bytes it decodes to the same packet; unstuff(stuff(x)) == x;
//  - a transaction either returns what it promised (a read: exactly `length` bytes; a ping: the id asked; a sync
//    read: per id nothing or `length` bytes, alerts only from ids asked) or throws DxlError of a declared kind with
//    a message - never another exception, never a read outside a buffer.
#include <fuzzer/FuzzedDataProvider.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <memory>
#include <vector>

#include "fuzz_check.hpp"
#include "plugins/dynamixel/dxl_bus.hpp"
#include "plugins/dynamixel/packet.hpp"

namespace {

using namespace rcand::plugins::dynamixel;
using Bytes = std::vector<std::uint8_t>;

// The serial line: each read_some hands out the next chunk; none left is a timeout (0), at once.
class ScriptedLink final : public SerialLink {
 public:
  explicit ScriptedLink(std::deque<Bytes> chunks) : chunks_(std::move(chunks)) {}
  void write(std::span<const std::uint8_t> bytes, Clock::time_point) override {
    RCAND_FUZZ_CHECK(!bytes.empty(), "the bus writes whole packets");
    ++writes_;
  }
  std::size_t read_some(std::span<std::uint8_t> out, Clock::time_point) override {
    if (chunks_.empty()) return 0;
    Bytes& chunk = chunks_.front();
    const std::size_t n = std::min(out.size(), chunk.size());
    std::copy_n(chunk.begin(), n, out.begin());
    chunk.erase(chunk.begin(), chunk.begin() + static_cast<std::ptrdiff_t>(n));
    if (chunk.empty()) chunks_.pop_front();
    return n;
  }
  void discard_input() override {}  // the reply is what arrives after the instruction: nothing is stale here
  void interrupt() noexcept override {}
  void clear_interrupt() noexcept override {}
  std::string path() const override { return "/dev/fuzz-ttyUSB0"; }
  int baud_rate() const override { return 1000000; }
  int writes() const { return writes_; }

 private:
  std::deque<Bytes> chunks_;
  int writes_ = 0;
};

bool same(const Packet& a, const Packet& b) { return a.id == b.id && a.code == b.code && a.params == b.params; }

std::vector<Packet> decode_all(Decoder& decoder) {
  std::vector<Packet> packets;
  while (auto packet = decoder.next()) packets.push_back(std::move(*packet));
  return packets;
}

void check_codec(const Bytes& stream, const std::deque<Bytes>& chunks) {
  RCAND_FUZZ_CHECK(unstuff(stuff(stream)) == stream, "unstuff undoes stuff");
  Decoder whole;
  whole.feed(stream);
  const auto at_once = decode_all(whole);
  Decoder pieces;
  std::vector<Packet> chunked;
  for (const auto& chunk : chunks) {
    pieces.feed(chunk);
    for (auto& packet : decode_all(pieces)) chunked.push_back(std::move(packet));
  }
  RCAND_FUZZ_CHECK(at_once.size() == chunked.size(), "chunking does not change how many packets decode");
  for (std::size_t i = 0; i < at_once.size(); ++i) {
    RCAND_FUZZ_CHECK(same(at_once[i], chunked[i]), "chunking does not change a packet");
    const Bytes wire = encode(at_once[i].id, at_once[i].code, at_once[i].params);
    if (wire.size() > 7 + Decoder::kMaxLength) continue;  // stuffing a header it let through grew it past the limit
    Decoder again;
    again.feed(wire);
    const auto round = again.next();
    RCAND_FUZZ_CHECK(round && same(*round, at_once[i]), "a decoded packet encodes to the same packet");
  }
}

std::uint8_t servo_id(FuzzedDataProvider& in) { return in.ConsumeIntegralInRange<std::uint8_t>(0, kMaxId); }

void run_transaction(std::uint8_t op, FuzzedDataProvider& in, DxlBus& bus) {
  switch (op % 6) {
    case 0: {
      const std::uint8_t id = servo_id(in);
      const PingReply reply = bus.ping(id);
      RCAND_FUZZ_CHECK(reply.id == id, "a ping answers for the id asked");
      break;
    }
    case 1: {
      (void)bus.scan();  // whatever it lists only ends up in an error text: the check is that it reads safely
      break;
    }
    case 2: {
      const std::uint8_t id = servo_id(in);
      const auto address = in.ConsumeIntegral<std::uint16_t>();
      const auto length = in.ConsumeIntegralInRange<std::uint16_t>(1, 8);
      bool alert = false;
      RCAND_FUZZ_CHECK(bus.read(id, address, length, &alert).size() == length, "a read returns the length asked");
      break;
    }
    case 3: {
      const std::uint8_t id = servo_id(in);
      const Bytes data{in.ConsumeIntegral<std::uint8_t>(), in.ConsumeIntegral<std::uint8_t>()};
      bool alert = false;
      bus.write(id, in.ConsumeIntegral<std::uint16_t>(), data, &alert);
      break;
    }
    case 4: bus.reboot(servo_id(in)); break;
    default: {
      const auto length = in.ConsumeIntegralInRange<std::uint16_t>(1, 8);
      Bytes ids(in.ConsumeIntegralInRange<std::size_t>(1, 4));
      for (auto& id : ids) id = servo_id(in);
      const auto result = bus.sync_read(in.ConsumeIntegral<std::uint16_t>(), length, ids);
      RCAND_FUZZ_CHECK(result.data.size() == ids.size(), "a sync read has one slot per id");
      for (const auto& data : result.data) RCAND_FUZZ_CHECK(!data || data->size() == length, "a slot holds the length asked");
      for (const auto id : result.alerted)
        RCAND_FUZZ_CHECK(std::find(ids.begin(), ids.end(), id) != ids.end(), "an alert comes from an id asked");
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 2) return 0;
  FuzzedDataProvider in(data + 1, size - 1);
  const std::uint8_t op = data[0];
  // The line's bytes and their chunking: up to 64 chunks from the front, the parameters from the back.
  Bytes stream;
  std::deque<Bytes> chunks;
  for (int i = 0; i < 64 && in.remaining_bytes() > 0; ++i) {
    const auto n = in.ConsumeIntegralInRange<std::size_t>(1, 64);
    Bytes chunk = in.ConsumeBytes<std::uint8_t>(n);
    if (chunk.empty()) break;
    stream.insert(stream.end(), chunk.begin(), chunk.end());
    chunks.push_back(std::move(chunk));
  }
  check_codec(stream, chunks);

  auto link = std::make_shared<ScriptedLink>(std::move(chunks));
  DxlBus bus(link, std::chrono::microseconds(0));
  try {
    run_transaction(op, in, bus);
  } catch (const DxlError& error) {
    RCAND_FUZZ_CHECK(error.kind() == DxlError::Kind::NoReply || error.kind() == DxlError::Kind::ServoError ||
                         error.kind() == DxlError::Kind::BadReply,
                     "a bus error has a declared kind");
    RCAND_FUZZ_CHECK(error.what()[0] != '\0', "a bus error explains itself");
  }
  RCAND_FUZZ_CHECK(link->writes() == 1, "one transaction writes one packet");
  return 0;
}
