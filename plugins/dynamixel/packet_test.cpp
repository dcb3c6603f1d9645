// The Protocol 2.0 codec against published vectors: the CRC catalogue's check value and the instruction and status
// packets printed in the ROBOTIS e-Manual (Protocol 2.0 page), whose CRCs were recomputed independently (Python,
// bitwise) before being written here. Also byte stuffing, the stream decoder, models and the latency timer.
#include <doctest/doctest.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include "latency_timer.hpp"
#include "models.hpp"
#include "packet.hpp"

using namespace rcand::plugins::dynamixel;
using Bytes = std::vector<std::uint8_t>;

namespace {

Bytes hex(const char* text) {
  Bytes out;
  std::istringstream in(text);
  unsigned value = 0;
  while (in >> std::hex >> value) out.push_back(static_cast<std::uint8_t>(value));
  return out;
}

Bytes params(std::uint16_t address, std::initializer_list<std::uint8_t> rest) {
  Bytes out;
  put_u16(out, address);
  for (const auto byte : rest) out.push_back(byte);
  return out;
}

}  // namespace

TEST_CASE("crc16: the catalogue check value of CRC-16/BUYPASS (poly 0x8005, init 0, unreflected)") {
  const std::string check = "123456789";
  CHECK(crc16(Bytes(check.begin(), check.end())) == 0xFEE8);
  CHECK(crc16(Bytes{}) == 0x0000);
}

TEST_CASE("encode: the e-Manual's instruction packets, byte for byte") {
  // Ping ID 1.
  CHECK(encode(1, inst::kPing, {}) == hex("FF FF FD 00 01 03 00 01 19 4E"));
  // Read ID 1: Present Position (132), 4 bytes.
  CHECK(encode(1, inst::kRead, params(132, {0x04, 0x00})) == hex("FF FF FD 00 01 07 00 02 84 00 04 00 1D 15"));
  // Write ID 1: Goal Position (116) = 512.
  CHECK(encode(1, inst::kWrite, params(116, {0x00, 0x02, 0x00, 0x00})) == hex("FF FF FD 00 01 09 00 03 74 00 00 02 00 00 CA 89"));
  // Reboot ID 1.
  CHECK(encode(1, inst::kReboot, {}) == hex("FF FF FD 00 01 03 00 08 2F 4E"));
  // Sync Read: Present Position (132), 4 bytes, of IDs 1 and 2.
  CHECK(encode(kBroadcastId, inst::kSyncRead, params(132, {0x04, 0x00, 0x01, 0x02})) ==
        hex("FF FF FD 00 FE 09 00 82 84 00 04 00 01 02 CE FA"));
  // Sync Write: Goal Position (116), 4 bytes: ID 1 = 150, ID 2 = 170.
  CHECK(encode(kBroadcastId, inst::kSyncWrite,
               params(116, {0x04, 0x00, 0x01, 0x96, 0x00, 0x00, 0x00, 0x02, 0xAA, 0x00, 0x00, 0x00})) ==
        hex("FF FF FD 00 FE 11 00 83 74 00 04 00 01 96 00 00 00 02 AA 00 00 00 82 87"));
}

TEST_CASE("decode: the e-Manual's status packets") {
  Decoder decoder;
  // Ping reply of ID 1: model 1030 (XM430-W210), firmware 0x26.
  decoder.feed(hex("FF FF FD 00 01 07 00 55 00 06 04 26 65 5D"));
  // Read reply of ID 1: 166 (Present Position).
  decoder.feed(hex("FF FF FD 00 01 08 00 55 00 A6 00 00 00 8C C0"));
  // Write reply of ID 1: no error.
  decoder.feed(hex("FF FF FD 00 01 04 00 55 00 A1 0C"));
  auto ping = decoder.next();
  REQUIRE(ping);
  CHECK(ping->id == 1);
  CHECK(ping->code == inst::kStatus);
  CHECK(ping->params == Bytes{0x00, 0x06, 0x04, 0x26});
  CHECK(get_u16(ping->params, 1) == 1030);
  auto read = decoder.next();
  REQUIRE(read);
  CHECK(get_i32(read->params, 1) == 166);
  auto write = decoder.next();
  REQUIRE(write);
  CHECK(write->params == Bytes{0x00});
  CHECK_FALSE(decoder.next());
  CHECK(decoder.dropped() == 0);
}

TEST_CASE("byte stuffing: FF FF FD in a body gains an FD, counted in LENGTH, covered by the CRC") {
  CHECK(stuff(Bytes{0x03, 0xFF, 0xFF, 0xFD, 0x01}) == Bytes{0x03, 0xFF, 0xFF, 0xFD, 0xFD, 0x01});
  CHECK(stuff(Bytes{0xFF, 0xFF, 0xFF, 0xFD}) == Bytes{0xFF, 0xFF, 0xFF, 0xFD, 0xFD});
  CHECK(stuff(Bytes{0xFF, 0xFD, 0xFF, 0xFF}) == Bytes{0xFF, 0xFD, 0xFF, 0xFF});  // no full pattern
  // Write ID 1 at 0x0000 the bytes FF FF FD: the body 03 00 00 FF FF FD gains an FD; LENGTH = 7 + CRC = 9.
  const auto packet = encode(1, inst::kWrite, Bytes{0x00, 0x00, 0xFF, 0xFF, 0xFD});
  CHECK(Bytes(packet.begin(), packet.end() - 2) == hex("FF FF FD 00 01 09 00 03 00 00 FF FF FD FD"));
  CHECK(get_u16(packet, packet.size() - 2) == crc16(std::span(packet).first(packet.size() - 2)));
  Decoder decoder;
  decoder.feed(packet);
  const auto back = decoder.next();
  REQUIRE(back);
  CHECK(back->params == Bytes{0x00, 0x00, 0xFF, 0xFF, 0xFD});

  // Random bodies round-trip, and a stuffed body never contains a header followed by anything but FD.
  std::mt19937 rng(17);
  for (int round = 0; round < 2000; ++round) {
    Bytes body(rng() % 24);
    for (auto& b : body) b = std::array<std::uint8_t, 4>{0xFF, 0xFD, 0x00, 0x55}[rng() % 4];
    const auto stuffed = stuff(body);
    CHECK(unstuff(stuffed) == body);
    for (std::size_t i = 0; i + 3 < stuffed.size(); ++i)
      if (stuffed[i] == 0xFF && stuffed[i + 1] == 0xFF && stuffed[i + 2] == 0xFD) CHECK(stuffed[i + 3] == 0xFD);
  }
}

TEST_CASE("decoder: split reads, noise, a corrupted CRC and an absurd length never crash or mislead") {
  const auto good = encode(3, inst::kStatus, Bytes{0x00, 0x10, 0x20});
  Decoder decoder;
  for (const auto byte : good) {  // one byte at a time
    CHECK_FALSE(decoder.next());
    decoder.feed(Bytes{byte});
  }
  REQUIRE(decoder.next());

  auto bad = good;
  bad[bad.size() - 1] ^= 0x01;
  decoder.feed(hex("00 FF 12 FF FF"));  // noise, with a partial header in it
  decoder.feed(bad);
  decoder.feed(hex("FF FF FD 00 05 FF FF"));  // a "header" with a 65535-byte length
  decoder.feed(good);
  const auto only = decoder.next();
  REQUIRE(only);
  CHECK(only->id == 3);
  CHECK_FALSE(decoder.next());
  CHECK(decoder.dropped() >= 2);

  std::mt19937 rng(5);
  for (int round = 0; round < 200; ++round) {  // garbage of every shape
    Bytes junk(rng() % 64);
    for (auto& b : junk) b = static_cast<std::uint8_t>(rng() % 3 == 0 ? 0xFF : rng());
    decoder.feed(junk);
    while (decoder.next()) {
    }
  }
}

TEST_CASE("models: per-model position resolution and units") {
  const auto xm = find_model(1020);
  REQUIRE(xm);
  CHECK(xm->name == "XM430-W350");
  CHECK(xm->table->goal_position == 116);
  CHECK(ticks_of(*xm, 0.0) == 2048);
  CHECK(ticks_of(*xm, 90.0) == 3072);
  CHECK(ticks_of(*xm, -180.0) == 0);
  CHECK(degrees_of(*xm, 1024) == doctest::Approx(-90.0));
  CHECK(velocity_units_of(*xm, 90.0) == 66);  // 15 rpm / 0.229
  CHECK(velocity_units_of(*xm, 0.01) == 1);   // never 0, which would mean "no limit"
  const auto ph = find_model(2020);
  REQUIRE(ph);
  CHECK(ph->table->goal_position == 564);
  CHECK(ticks_of(*ph, 180.0) == 501923);
  CHECK(ticks_of(*ph, 90.0) == 250962);  // 1,003,846 ticks a turn: 90 deg is a quarter, rounded
  CHECK(degrees_of(*ph, -501923) == doctest::Approx(-180.0));
  CHECK(find_model(1060)->name == "XL430-W250");
  CHECK_FALSE(find_model(12));  // AX-12A speaks Protocol 1.0
  CHECK(hardware_error_text(0x24) == "overheating, overload");
}

TEST_CASE("latency timer: 16 ms warns with the fix, 1 ms is fine, a non-USB port has none") {
  const auto root = std::filesystem::temp_directory_path() / ("rcand-dxl-sysfs-" + std::to_string(::getpid()));
  const auto dir = root / "bus/usb-serial/devices/ttyUSB0";
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "latency_timer") << "16\n";
  auto timer = read_latency_timer("/dev/ttyUSB0", root.string());
  REQUIRE(timer);
  CHECK(timer->milliseconds == 16);
  CHECK(latency_timer_warning(*timer).find("latency timer is 16 ms") != std::string::npos);
  CHECK(latency_timer_warning(*timer).find("echo 1 | sudo tee " + (dir / "latency_timer").string()) != std::string::npos);
  std::ofstream(dir / "latency_timer") << "1\n";
  CHECK(latency_timer_warning(*read_latency_timer("/dev/ttyUSB0", root.string())).empty());
  CHECK_FALSE(read_latency_timer("/dev/ttyAMA0", root.string()));
  std::filesystem::remove_all(root);
}
