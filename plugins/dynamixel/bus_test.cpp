// Protocol 2.0 transactions over a real pseudo-terminal against the servo emulator: ping and scan, read and write,
// a 6-servo sync write / sync read round trip, a missing servo, the Alert bit and Hardware Error Status, reboot.
#include <doctest/doctest.h>

#include <memory>

#include "dxl_bus.hpp"
#include "models.hpp"
#include "posix_serial.hpp"
#include "testing/pty_pair.hpp"
#include "testing/servo_emulator.hpp"

using namespace rcand::plugins::dynamixel;
using namespace std::chrono_literals;
using testing::PtyPair;
using testing::ServoEmulator;

namespace {

struct Bench {
  PtyPair pty;
  ServoEmulator emulator{pty.master(), {1, 2, 3, 4, 5, 6}};
  std::shared_ptr<PosixSerial> link = std::make_shared<PosixSerial>(pty.slave_path(), 1000000);
  DxlBus bus{link, 20ms};
};

std::vector<std::uint8_t> u32(std::int32_t v) {
  std::vector<std::uint8_t> out;
  put_u32(out, static_cast<std::uint32_t>(v));
  return out;
}

}  // namespace

TEST_CASE("a late reply: a ping with tries takes it, a scan after a missed ping lists its servo once") {
  Bench b;
  b.emulator.hold_next_reply(3);
  CHECK(b.bus.ping(3, 3).id == 3);  // the first try's reply comes late, with the second try's

  b.emulator.hold_next_reply(3);
  CHECK_THROWS_AS(b.bus.ping(3), DxlError);
  const auto found = b.bus.scan();  // the late reply arrives ahead of the broadcast's answers
  std::vector<int> ids;
  for (const auto& reply : found) ids.push_back(reply.id);
  CHECK(ids == std::vector<int>{1, 2, 3, 4, 5, 6});
}

TEST_CASE("ping, scan, read and write") {
  Bench b;
  const auto reply = b.bus.ping(3);
  CHECK(reply.id == 3);
  CHECK(reply.model == 1020);
  CHECK_FALSE(reply.alert);
  b.emulator.set_present(5, false);
  const auto found = b.bus.scan();
  REQUIRE(found.size() == 5);
  CHECK(found.front().id == 1);
  CHECK(found.back().id == 6);
  CHECK_THROWS_AS(b.bus.ping(5), DxlError);
  try {
    b.bus.ping(5);
  } catch (const DxlError& e) {
    CHECK(e.kind() == DxlError::Kind::NoReply);
    CHECK(std::string(e.what()).find("no answer from Dynamixel ID 5 (ping) at 1000000 bps on " + b.pty.slave_path()) == 0);
  }
  CHECK_THROWS_WITH_AS(b.bus.ping(5, 3), doctest::Contains("no answer from Dynamixel ID 5 (ping, 3 tries)"), DxlError);
  b.bus.write(2, kTableX.goal_position, u32(1234));
  CHECK(get_i32(b.bus.read(2, kTableX.goal_position, 4), 0) == 1234);
  // EEPROM with the torque on: the servo refuses, and the error names it.
  b.bus.write(2, kTableX.torque_enable, std::vector<std::uint8_t>{1});
  CHECK_THROWS_WITH_AS(b.bus.write(2, kTableX.operating_mode, std::vector<std::uint8_t>{1}),
                       "Dynamixel ID 2 refused a write: access error", DxlError);
}

TEST_CASE("sync write then sync read: six servos, one packet each way") {
  Bench b;
  std::vector<std::pair<std::uint8_t, std::vector<std::uint8_t>>> items;
  for (std::uint8_t id = 1; id <= 6; ++id) items.emplace_back(id, u32(1000 + 100 * id));
  b.emulator.clear_received();
  b.bus.sync_write(kTableX.goal_position, 4, items);
  const std::vector<std::uint8_t> ids{1, 2, 3, 4, 5, 6};
  const auto result = b.bus.sync_read(kTableX.goal_position, 4, ids);
  REQUIRE(result.data.size() == 6);
  for (std::size_t i = 0; i < 6; ++i) {
    REQUIRE(result.data[i]);
    CHECK(get_i32(*result.data[i], 0) == 1100 + 100 * static_cast<int>(i));
  }
  const auto received = b.emulator.received();
  REQUIRE(received.size() == 2);  // exactly one instruction packet per direction of the round trip
  CHECK(received[0].packet.code == inst::kSyncWrite);
  CHECK(received[1].packet.code == inst::kSyncRead);

  // A missing servo costs its own slot only.
  b.emulator.set_present(4, false);
  const auto partial = b.bus.sync_read(kTableX.goal_position, 4, ids);
  CHECK(partial.data[2].has_value());
  CHECK_FALSE(partial.data[3].has_value());
  CHECK(partial.data[4].has_value());
}

TEST_CASE("hardware error: the Alert bit on every reply, Hardware Error Status, and reboot clears it") {
  Bench b;
  b.emulator.set_hardware_error(2, 0x20);  // overload
  bool alert = false;
  const auto bits = b.bus.read(2, kTableX.hardware_error, 1, &alert);
  CHECK(alert);
  CHECK(bits[0] == 0x20);
  CHECK(hardware_error_text(bits[0]) == "overload");
  const auto sync = b.bus.sync_read(kTableX.present_position, 4, {1, 2, 3});
  CHECK(sync.alerted == std::vector<std::uint8_t>{2});
  CHECK(sync.data[1].has_value());  // the Alert bit is not an error of the instruction
  b.bus.reboot(2);
  CHECK(b.emulator.servo(2).reboots == 1);
  CHECK(b.bus.read(2, kTableX.hardware_error, 1, &alert)[0] == 0);
  CHECK_FALSE(alert);
}

TEST_CASE("serial: a missing device is a named fault, with the device, the OS error and a hint apart") {
  CHECK_THROWS_WITH_AS(
      PosixSerial("/dev/ttyUSB-rcand-none", 1000000),
      doctest::Contains("cannot open /dev/ttyUSB-rcand-none: No such file or directory (is the U2D2 plugged in?"), SerialError);
  try {
    PosixSerial("/dev/ttyUSB-rcand-none", 1000000);
    FAIL("opened a device that does not exist");
  } catch (const rcand::sdk::DeviceFault& fault) {  // what the kernel shows apart (GET /api/status)
    CHECK(fault.message() == "cannot open /dev/ttyUSB-rcand-none: No such file or directory");
    CHECK(fault.device() == "/dev/ttyUSB-rcand-none");
    CHECK(fault.os_error() == "No such file or directory");
    CHECK(fault.hint().starts_with("is the U2D2 plugged in? ls /dev/serial/by-id/"));
  }
}
