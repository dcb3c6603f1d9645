// The Feetech packet codec against vectors derived by hand from the frame rule (FF FF id len code params, checksum
// = ~(id + len + code + params) & 0xFF; Feetech's SCServo SDK protocol_packet_handler.py and the packet builders of
// LeRobot's tests/mocks/mock_feetech.py compute the same sum), the decoder on split, noisy and corrupt streams, and
// the STS sign-magnitude encoding (lerobot encoding_utils.py).
#include <doctest/doctest.h>

#include "protocol.hpp"

using namespace rcand::plugins::feetech;
using Bytes = std::vector<std::uint8_t>;

TEST_CASE("feetech codec: instruction packets byte for byte") {
  // PING id 1: 1 + 2 + 1 = 4, ~4 = FB (the e-manual's own example packet).
  CHECK(encode(1, inst::kPing, {}) == Bytes{0xFF, 0xFF, 0x01, 0x02, 0x01, 0xFB});
  // READ id 1, present position (56 = 0x38), 2 bytes: 1 + 4 + 2 + 0x38 + 2 = 0x41 -> BE.
  CHECK(encode(1, inst::kRead, Bytes{0x38, 0x02}) == Bytes{0xFF, 0xFF, 0x01, 0x04, 0x02, 0x38, 0x02, 0xBE});
  // WRITE id 1, goal position (42 = 0x2A) = 2048, little-endian 00 08: 1 + 5 + 3 + 0x2A + 8 = 0x3B -> C4.
  CHECK(encode(1, inst::kWrite, Bytes{0x2A, 0x00, 0x08}) == Bytes{0xFF, 0xFF, 0x01, 0x05, 0x03, 0x2A, 0x00, 0x08, 0xC4});
  // SYNC WRITE goal position to ids 1 (2048) and 2 (1024): sum 0x1C6 -> 39.
  CHECK(encode(kBroadcastId, inst::kSyncWrite, Bytes{0x2A, 0x02, 0x01, 0x00, 0x08, 0x02, 0x00, 0x04}) ==
        Bytes{0xFF, 0xFF, 0xFE, 0x0A, 0x83, 0x2A, 0x02, 0x01, 0x00, 0x08, 0x02, 0x00, 0x04, 0x39});
  // SYNC READ 8 bytes from 56 of ids 1, 2, 3: sum 0x1CD -> 32.
  CHECK(encode(kBroadcastId, inst::kSyncRead, Bytes{0x38, 0x08, 0x01, 0x02, 0x03}) ==
        Bytes{0xFF, 0xFF, 0xFE, 0x07, 0x82, 0x38, 0x08, 0x01, 0x02, 0x03, 0x32});
  CHECK(checksum(Bytes{0xFE, 0x04, 0x03, 0x28, 0x01}) == static_cast<std::uint8_t>(~(0xFE + 0x04 + 0x03 + 0x28 + 0x01)));
}

TEST_CASE("feetech codec: the decoder takes status packets from a split, noisy stream and drops corrupt ones") {
  // A status reply of id 1: error 0, present position 2048: 1 + 4 + 0 + 0 + 8 = 0x0D -> F2.
  const Bytes reply{0xFF, 0xFF, 0x01, 0x04, 0x00, 0x00, 0x08, 0xF2};
  Decoder decoder;
  Bytes noisy{0x00, 0xFF, 0x13};
  noisy.insert(noisy.end(), reply.begin(), reply.end());
  for (const auto b : noisy) decoder.feed(Bytes{b});  // one byte at a time
  auto packet = decoder.next();
  REQUIRE(packet);
  CHECK(packet->id == 1);
  CHECK(packet->code == 0);
  CHECK(packet->params == Bytes{0x00, 0x08});
  CHECK(get_u16(packet->params, 0) == 2048);
  CHECK_FALSE(decoder.next());

  Bytes corrupt = reply;
  corrupt[6] ^= 0x01;                                          // the checksum no longer matches
  const Bytes ping_reply{0xFF, 0xFF, 0x02, 0x02, 0x20, 0xDB};  // id 2 answers with the overload bit: 2 + 2 + 0x20 = 0x24 -> DB
  decoder.feed(corrupt);
  decoder.feed(ping_reply);
  packet = decoder.next();
  REQUIRE(packet);
  CHECK(packet->id == 2);
  CHECK(packet->code == status_bit::kOverload);
  CHECK(packet->params.empty());
  CHECK(decoder.dropped() >= 1);
  CHECK(first_status_text(packet->code) == "overloaded");

  // A length that leaves no room for the code and the checksum is not a packet.
  decoder.clear();
  decoder.feed(Bytes{0xFF, 0xFF, 0x01, 0x01, 0xFF, 0xFF, 0x01, 0x02, 0x00, 0xFC});
  packet = decoder.next();
  REQUIRE(packet);
  CHECK(packet->id == 1);
  CHECK(packet->params.empty());
}

TEST_CASE("feetech codec: STS sign-magnitude (bit 15 for speeds and positions, bit 10 for the load) and both endians") {
  CHECK(encode_sign_magnitude(100, 15) == 0x0064);
  CHECK(encode_sign_magnitude(-100, 15) == 0x8064);
  CHECK(decode_sign_magnitude(0x8064, 15) == -100);
  CHECK(decode_sign_magnitude(0x0FFF, 15) == 4095);
  CHECK(encode_sign_magnitude(-5, 10) == 0x0405);
  CHECK(decode_sign_magnitude(0x0405, 10) == -5);
  CHECK(encode_sign_magnitude(-40000, 15) == 0xFFFF);  // saturates, never wraps into the sign
  std::vector<std::uint8_t> out;
  put_u16(out, 0x0800);
  put_u16(out, 0x0800, Endian::Big);  // SCS (protocol 1)
  CHECK(out == Bytes{0x00, 0x08, 0x08, 0x00});
  CHECK(get_u16(out, 2, Endian::Big) == 0x0800);
}
