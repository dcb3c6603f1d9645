// Issue 17 benchmarks on the fake buses CI has: halt() latency of the PCA9685 driver (fake register-map bus), the
// Dynamixel driver (6 emulated servos on a pseudo-terminal, replies timed as on a 1 Mbps wire, status polls running)
// and the GPIO H-bridge driver (fake chip); then a 100 Hz sync write + sync read loop for the 6 servos with its
// jitter; the same for the Feetech driver (6 emulated STS3215 servos, 1 Mbps wire timing); and the Arduino bridge
// driver (the bridge firmware's emulator on a pseudo-terminal, heartbeat and ultrasonic polls running), with the port
// answering and hung. Target: halt() <= 2 ms on each (the Arduino's deadline on a hung port is its halt_deadline_ms,
// 10 ms).
//   bench_hw_halt [samples] [loop_cycles]
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>
#include <vector>

#include "arduino/arduino_driver.hpp"
#include "arduino/testing/arduino_emulator.hpp"
#include "arduino/testing/arduino_pty.hpp"
#include "dynamixel/dynamixel_driver.hpp"
#include "dynamixel/posix_serial.hpp"
#include "dynamixel/testing/pty_pair.hpp"
#include "dynamixel/testing/servo_emulator.hpp"
#include "feetech/feetech_driver.hpp"
#include "feetech/testing/sts_emulator.hpp"
#include "gpio_motor/gpio_motor_drive.hpp"
#include "gpio_motor/testing/fake_gpio.hpp"
#include "pca9685/fake_pca9685_bus.hpp"
#include "pca9685/pca9685_drive.hpp"

using namespace std::chrono;
using nlohmann::json;
namespace dxl = rcand::plugins::dynamixel;
namespace fts = rcand::plugins::feetech;
namespace ard = rcand::plugins::arduino;
namespace gpio = rcand::plugins::gpio_motor;
namespace pca = rcand::plugins::pca9685;

namespace {

using Clock = steady_clock;

void report(const char* what, std::vector<double> us) {
  std::sort(us.begin(), us.end());
  const auto at = [&](double q) {
    return us[std::min(us.size() - 1, static_cast<std::size_t>(q * static_cast<double>(us.size())))];
  };
  std::printf("%-44s n=%-5zu p50 %8.1f us  p99 %8.1f us  max %8.1f us\n", what, us.size(), at(0.5), at(0.99), us.back());
}

template <class F> double time_us(F&& f) {
  const auto t0 = Clock::now();
  f();
  return duration<double, std::micro>(Clock::now() - t0).count();
}

void bench_pca9685(int samples) {
  auto bus = std::make_shared<pca::testing::FakePca9685Bus>();
  const auto settings = pca::Pca9685Settings::from(rcand::sdk::ConfigView(json::parse(
      R"({"pwm_frequency_hz": 1000, "channels": {"left": {"pwm": 0, "in1": 1, "in2": 2}, "right": {"pwm": 5, "in1": 3, "in2": 4}}})")));
  pca::Pca9685Drive drive(settings, bus, nullptr);
  drive.start();
  std::vector<double> us;
  for (int i = 0; i < samples; ++i) {
    drive.set_wheel_speeds(0.5, -0.5);
    us.push_back(time_us([&] { drive.halt(); }));
  }
  report("pca9685 halt() (fake bus, 1 block write)", us);
}

void bench_gpio(int samples) {
  auto log = std::make_shared<gpio::testing::EventLog>();
  auto chip = std::make_shared<gpio::testing::FakeChip>(log);
  const auto settings = gpio::GpioMotorSettings::from(rcand::sdk::ConfigView(json::parse(
      R"({"channels": {"left": {"in1": 17, "in2": 27, "enable": 22, "pwm": {"chip": 0, "channel": 0}},
                       "right": {"in1": 23, "in2": 24, "enable": 25, "pwm": {"chip": 0, "channel": 1}}}})")));
  gpio::GpioMotorDrive drive(settings, chip, [log](const gpio::PwmSettings& p) {
    return std::make_unique<gpio::testing::FakePwm>(log, "pwm" + std::to_string(p.channel));
  });
  drive.start();
  std::vector<double> us;
  for (int i = 0; i < samples; ++i) {
    drive.set_wheel_speeds(0.5, -0.5);
    us.push_back(time_us([&] { drive.halt(); }));
    if (i % 64 == 0) log->clear();
  }
  report("gpio halt() (fake chip, 8 line changes)", us);
}

json arm(const std::string& port) {
  json servos = json::array();
  for (int i = 1; i <= 6; ++i)
    servos.push_back({{"id", i}, {"joint", "j" + std::to_string(i)}, {"min_deg", -150}, {"max_deg", 150}});
  return {{"port", port}, {"baud_rate", 1000000}, {"servos", servos}, {"poll_hz", 100}, {"reply_timeout_ms", 5}};
}

void bench_dynamixel_halt(int samples) {
  dxl::testing::PtyPair pty;
  dxl::testing::ServoEmulator emulator(pty.master(), {1, 2, 3, 4, 5, 6});
  emulator.set_wire_baud(1000000);
  dxl::DynamixelDriver driver(dxl::DynamixelSettings::from(rcand::sdk::ConfigView(arm(pty.slave_path()))),
                              std::make_shared<dxl::PosixSerial>(pty.slave_path(), 1000000));
  driver.start();
  std::vector<double> returned, applied;
  const auto is_halt = [](const dxl::testing::ServoEmulator::Received& r) {
    return r.packet.code == dxl::inst::kSyncWrite && dxl::get_u16(r.packet.params, 0) == dxl::kTableX.goal_velocity;
  };
  for (int i = 0; i < samples; ++i) {
    driver.set_joint_targets({{"j1", (i % 2 ? 30.0 : -30.0), 60.0}});
    // Land the halt at a random point of the 10 ms poll cycle, so some of them interrupt a sync read.
    std::this_thread::sleep_for(microseconds(2000 + (i * 977) % 9000));
    emulator.clear_received();
    const auto t0 = Clock::now();
    driver.halt();
    returned.push_back(duration<double, std::micro>(Clock::now() - t0).count());
    emulator.wait_for_packets([&](const auto& received) { return std::any_of(received.begin(), received.end(), is_halt); },
                              milliseconds(100));
    for (const auto& r : emulator.received())
      if (is_halt(r)) applied.push_back(duration<double, std::micro>(r.at - t0).count());
  }
  report("dynamixel halt() (pty, 6 servos, polls at 100 Hz)", returned);
  report("dynamixel halt() -> sync write at the servos", applied);
}

// The Arduino bridge at 115200 baud: halt() while the heartbeat (100 ms) and the ultrasonic poll (20 Hz) run, the stop
// line as the emulated firmware reads it, and halt() with the port hung while a heartbeat waits for its ack.
void bench_arduino_halt(int samples) {
  ard::testing::ArduinoPty pty;
  ard::testing::ArduinoEmulator emulator(pty.master());
  auto settings = ard::ArduinoSettings::from(rcand::sdk::ConfigView(
      json{{"port", pty.slave_path()}, {"heartbeat_ms", 100}, {"timeout_s", 0.5}, {"ultrasonic", {{"poll_hz", 20}}}}));
  ard::ArduinoDriver driver(settings, std::make_shared<ard::ArduinoBus>(settings.port, settings.baud));
  driver.start();
  using Board = ard::testing::ArduinoEmulator::Board;
  using Lines = std::vector<ard::testing::ArduinoEmulator::Line>;
  std::vector<double> returned, applied, hung;
  for (int i = 0; i < samples; ++i) {
    driver.set_wheel_speeds(0.5, -0.5);
    std::this_thread::sleep_for(microseconds(2000 + (i * 977) % 40000));  // anywhere in the heartbeat and poll cycles
    emulator.clear_received();
    const auto t0 = Clock::now();
    driver.halt();
    returned.push_back(duration<double, std::micro>(Clock::now() - t0).count());
    emulator.wait_until([](const Board& b, const Lines&) { return !b.moving(); }, milliseconds(200));
    for (const auto& line : emulator.received())
      if (line.text == "{\"cmd\":\"stop\"}") {
        applied.push_back(duration<double, std::micro>(line.at - t0).count());
        break;
      }
  }
  for (int i = 0; i < std::max(1, samples / 10); ++i) {
    driver.set_wheel_speeds(0.5, 0.5);
    emulator.set_hung(true);
    std::this_thread::sleep_for(milliseconds(150));  // a heartbeat or poll is written and waits for its reply
    hung.push_back(time_us([&] { driver.halt(); }));
    emulator.set_hung(false);
    emulator.wait_until([](const Board& b, const Lines& l) { return !b.moving() && !l.empty(); }, milliseconds(2000));
  }
  report("arduino halt() (pty, heartbeat + 20 Hz polls)", returned);
  report("arduino halt() -> stop line at the board", applied);
  report("arduino halt() on a hung port", hung);
}

void bench_dynamixel_loop(int cycles) {
  dxl::testing::PtyPair pty;
  dxl::testing::ServoEmulator emulator(pty.master(), {1, 2, 3, 4, 5, 6});
  emulator.set_wire_baud(1000000);
  dxl::DxlBus bus(std::make_shared<dxl::PosixSerial>(pty.slave_path(), 1000000), milliseconds(3));
  const std::vector<std::uint8_t> ids{1, 2, 3, 4, 5, 6};
  for (const auto id : ids) bus.write(id, dxl::kTableX.torque_enable, std::vector<std::uint8_t>{1});
  std::vector<double> jitter, busy;
  int missing = 0;
  const auto period = milliseconds(10);
  auto next = Clock::now() + period;
  for (int c = 0; c < cycles; ++c) {
    std::this_thread::sleep_until(next);
    const auto start = Clock::now();
    jitter.push_back(duration<double, std::micro>(start - next).count());
    std::vector<std::pair<std::uint8_t, std::vector<std::uint8_t>>> items;
    for (const auto id : ids) {
      std::vector<std::uint8_t> goal;
      dxl::put_u32(goal, static_cast<std::uint32_t>(2048 + ((c * 7 + id * 100) % 400)));
      items.emplace_back(id, std::move(goal));
    }
    bus.sync_write(dxl::kTableX.goal_position, 4, items);
    const auto read = bus.sync_read(dxl::kTableX.present_velocity, 8, ids);
    for (const auto& d : read.data) missing += !d;
    busy.push_back(duration<double, std::micro>(Clock::now() - start).count());
    next += period;
  }
  report("100 Hz loop: cycle start jitter", jitter);
  report("100 Hz loop: sync write + sync read of 6", busy);
  std::printf("100 Hz loop: %d cycles, %d servo replies missing\n", cycles, missing);
}

void bench_feetech_halt(int samples) {
  dxl::testing::PtyPair pty;
  fts::testing::StsEmulator emulator(pty.master(), {1, 2, 3, 4, 5, 6});
  emulator.set_wire_baud(1000000);
  fts::FeetechDriver driver(fts::FeetechSettings::from(rcand::sdk::ConfigView(arm(pty.slave_path()))),
                            std::make_shared<dxl::PosixSerial>(pty.slave_path(), 1000000));
  driver.start();
  std::vector<double> returned, applied;
  // The halt is the only sync write of all six servos (a command here names one joint).
  const auto is_halt = [](const fts::testing::StsEmulator::Received& r) {
    return r.packet.code == fts::inst::kSyncWrite && r.packet.params.size() == 2 + 6 * (1 + fts::sts::kCommandBlockLength);
  };
  for (int i = 0; i < samples; ++i) {
    driver.set_joint_targets({{"j1", (i % 2 ? 30.0 : -30.0), 60.0}});
    std::this_thread::sleep_for(microseconds(2000 + (i * 977) % 9000));  // anywhere in the 10 ms poll cycle
    emulator.clear_received();
    const auto t0 = Clock::now();
    driver.halt();
    returned.push_back(duration<double, std::micro>(Clock::now() - t0).count());
    emulator.wait_for_packets([&](const auto& received) { return std::any_of(received.begin(), received.end(), is_halt); },
                              milliseconds(100));
    for (const auto& r : emulator.received())
      if (is_halt(r)) applied.push_back(duration<double, std::micro>(r.at - t0).count());
  }
  report("feetech halt() (pty, 6 STS servos, 100 Hz polls)", returned);
  report("feetech halt() -> sync write at the servos", applied);
}

void bench_feetech_loop(int cycles) {
  dxl::testing::PtyPair pty;
  fts::testing::StsEmulator emulator(pty.master(), {1, 2, 3, 4, 5, 6});
  emulator.set_wire_baud(1000000);
  fts::FeetechBus bus(std::make_shared<dxl::PosixSerial>(pty.slave_path(), 1000000), milliseconds(3));
  const std::vector<std::uint8_t> ids{1, 2, 3, 4, 5, 6};
  for (const auto id : ids) bus.write(id, fts::sts::kTorqueEnable, std::vector<std::uint8_t>{1});
  std::vector<double> jitter, busy;
  int missing = 0;
  const auto period = milliseconds(10);
  auto next = Clock::now() + period;
  for (int c = 0; c < cycles; ++c) {
    std::this_thread::sleep_until(next);
    const auto start = Clock::now();
    jitter.push_back(duration<double, std::micro>(start - next).count());
    fts::SyncItems items;
    for (const auto id : ids) {
      std::vector<std::uint8_t> goal;
      fts::put_u16(goal, static_cast<std::uint16_t>(2048 + ((c * 7 + id * 100) % 400)));
      items.emplace_back(id, std::move(goal));
    }
    bus.sync_write(fts::sts::kGoalPosition, 2, items);
    const auto read = bus.sync_read(fts::sts::kStatusBlock, fts::sts::kStatusBlockLength, ids);
    for (const auto& d : read.data) missing += !d;
    busy.push_back(duration<double, std::micro>(Clock::now() - start).count());
    next += period;
  }
  report("feetech 100 Hz loop: cycle start jitter", jitter);
  report("feetech 100 Hz loop: sync write + read of 6", busy);
  std::printf("feetech 100 Hz loop: %d cycles, %d servo replies missing\n", cycles, missing);
}

}  // namespace

int main(int argc, char** argv) {
  const int samples = argc > 1 ? std::atoi(argv[1]) : 500;
  const int cycles = argc > 2 ? std::atoi(argv[2]) : 1000;
  bench_pca9685(samples);
  bench_gpio(samples);
  bench_dynamixel_halt(samples);
  bench_dynamixel_loop(cycles);
  bench_feetech_halt(samples);
  bench_feetech_loop(cycles);
  bench_arduino_halt(samples);
}
