// The Feetech driver on a pseudo-terminal against emulated STS3215 servos: start-up (hold where it is, torque on,
// the mode set through the EEPROM lock), joint poses as one sync write at the commanded speed, the speed cap, the
// torque limit, halt as one sync write that holds the arm with the torque on (and does not wait behind a poll),
// wheel mode and its halt, the lost-servo fault, and the plugin through the fake host.
#include <doctest/doctest.h>

#include <rcand/sdk/testing/fake_host.hpp>
#include <rcand/sdk/testing/recording_logger.hpp>

#include <condition_variable>
#include <fstream>
#include <mutex>

#include "dynamixel/posix_serial.hpp"
#include "dynamixel/testing/pty_pair.hpp"
#include "feetech_driver.hpp"
#include "testing/sts_emulator.hpp"

extern "C" const rcand_plugin_descriptor* RCAND_ENTRY_FUNCTION(void);

using namespace rcand::plugins::feetech;
using namespace std::chrono_literals;
using nlohmann::json;
using rcand::plugins::dynamixel::PosixSerial;
using rcand::plugins::dynamixel::testing::PtyPair;
using testing::StsEmulator;
using StsServos = std::map<std::uint8_t, StsEmulator::Servo>;

namespace {

json so_arm_config(const std::string& port) {
  // An SO-ARM101-like arm: six STS3215 joints. 50 ms for an answer: the emulator is a thread of this test, and a
  // loaded machine (CI's sanitizer build) delays it.
  json servos = json::array();
  for (int i = 1; i <= 6; ++i)
    servos.push_back({{"id", i}, {"joint", "j" + std::to_string(i)}, {"min_deg", -150}, {"max_deg", 150}});
  return {{"port", port},     {"baud_rate", 1000000}, {"model", "sts3215"},
          {"servos", servos}, {"poll_hz", 100},       {"reply_timeout_ms", 50}};
}

json wheel_config(const std::string& port) {
  return {{"port", port},
          {"servos", {{{"id", 7}, {"wheel", "left"}}, {{"id", 8}, {"wheel", "right"}, {"invert", true}}}},
          {"poll_hz", 100},
          {"reply_timeout_ms", 50}};
}

struct StsRig {
  PtyPair pty;
  StsEmulator emulator;
  rcand::sdk::testing::LogSink sink;
  rcand::sdk::testing::RecordingLogger log{sink, "plugin.org.rcand.feetech"};
  std::unique_ptr<FeetechDriver> driver;

  explicit StsRig(std::vector<std::uint8_t> ids = {1, 2, 3, 4, 5, 6}) : emulator(pty.master(), std::move(ids)) {}
  void make(const json& config) {
    driver = std::make_unique<FeetechDriver>(FeetechSettings::from(rcand::sdk::ConfigView(config)),
                                             std::make_shared<PosixSerial>(pty.slave_path(), 1000000), &log);
  }
  // Instruction packets other than the status poll's sync reads.
  static std::vector<Packet> commands_in(const std::vector<StsEmulator::Received>& received) {
    std::vector<Packet> out;
    for (const auto& r : received)
      if (r.packet.code != inst::kSyncRead) out.push_back(r.packet);
    return out;
  }
  std::vector<Packet> commands() const { return commands_in(emulator.received()); }
  bool wait_for_command() {
    return emulator.wait_for_packets([](const auto& received) { return !commands_in(received).empty(); }, 2s);
  }
  bool logged(const std::string& text) const {
    for (const auto& line : sink.lines())
      if (line.find(text) != std::string::npos) return true;
    return false;
  }
};

std::string feetech_error_of(const std::function<void()>& call) {
  try {
    call();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "no error";
}

bool all_still(const StsServos& servos) {
  for (const auto& entry : servos)
    if (entry.second.signed16(sts::kPresentSpeed) != 0) return false;
  return true;
}

}  // namespace

TEST_CASE("feetech start: each servo held where it is, torque on, position mode set through the EEPROM lock") {
  StsRig rig;
  rig.emulator.set_position(3, 3000);
  rig.emulator.set_operating_mode(2, sts::kModeWheel);  // left in wheel mode: the EEPROM must be unlocked to change it
  rig.make(so_arm_config(rig.pty.slave_path()));
  rig.driver->start();
  for (std::uint8_t id = 1; id <= 6; ++id) {
    const auto s = rig.emulator.servo(id);
    CAPTURE(id);
    CHECK(s.u8(sts::kTorqueEnable) == 1);
    CHECK(s.u8(sts::kOperatingMode) == sts::kModePosition);
    CHECK(s.u8(sts::kLock) == 1);
    CHECK(s.u16(sts::kTorqueLimit) == 1000);
    CHECK(s.eeprom_refused == 0);
  }
  CHECK(rig.emulator.servo(3).signed16(sts::kGoalPosition) == 3000);  // no jump when the torque came on
  CHECK(rig.driver->interface_name() == "joint_arm");
  const auto states = rig.driver->joint_states();
  REQUIRE(states.size() == 6);
  CHECK(states[2].joint == "j3");
  CHECK(states[2].position_deg.value_or(-999) == doctest::Approx((3000 - 2048) * 360.0 / 4096));
  CHECK(states[2].torque_on);
  const auto status = rig.driver->status();
  CHECK(status["servos"][0]["model"] == "sts3215");
  CHECK(status["fail_safe"].get<std::string>().find("no bus watchdog") != std::string::npos);
  CHECK_FALSE(status.contains("fault"));
  CHECK(rig.logged("feetech on " + rig.pty.slave_path() + " at 1000000 bps"));
}

TEST_CASE("feetech joint targets: one sync write at the commanded speed; a wrong joint or range applies nothing") {
  StsRig rig;
  rig.make(so_arm_config(rig.pty.slave_path()));
  rig.driver->start();
  rig.emulator.clear_received();
  rig.driver->set_joint_targets({{"j1", 45.0, 0.0}, {"j2", -30.0, 180.0}});
  REQUIRE(rig.wait_for_command());
  const auto sent = rig.commands();
  REQUIRE(sent.size() == 1);
  CHECK(sent[0].code == inst::kSyncWrite);
  CHECK(sent[0].params[0] == sts::kGoalPosition);
  CHECK(sent[0].params[1] == 8);
  CHECK(sent[0].params.size() == 2 + 2 * 9);
  CHECK(rig.emulator.wait_until([](const StsServos& s) { return s.at(1).signed16(sts::kPresentPosition) == 2048 + 512; }, 3s));
  CHECK(rig.emulator.servo(1).u16(sts::kGoalSpeed) == 1024);  // the default 90 deg/s = 1024 steps/s
  CHECK(rig.emulator.servo(2).signed16(sts::kGoalPosition) == 2048 - 341);
  CHECK(rig.emulator.servo(2).u16(sts::kGoalSpeed) == 2048);  // 180 deg/s

  rig.emulator.clear_received();
  CHECK(feetech_error_of([&] {
          rig.driver->set_joint_targets({{"j1", 0.0, 0.0}, {"elbow", 0.0, 0.0}});
        }) == "joint 'elbow': not a joint of this Feetech bus");
  CHECK(feetech_error_of([&] {
          rig.driver->set_joint_targets({{"j1", 0.0, 0.0}, {"j3", 151.0, 0.0}});
        }).find("joint 'j3': 151.000000 deg is outside the servo's range [-150") == 0);
  CHECK(rig.commands().empty());
  CHECK(rig.emulator.servo(1).signed16(sts::kGoalPosition) == 2048 + 512);
  CHECK_THROWS_AS(rig.driver->set_wheel_speeds(1, 1), std::logic_error);  // an arm has no wheels
}

TEST_CASE("feetech velocity cap, torque limit, invert and offset, and the servo's own angle limits") {
  StsRig rig;
  rig.emulator.set_angle_limits(4, 1024, 3072);  // the servo allows -90..90 deg only
  auto config = so_arm_config(rig.pty.slave_path());
  config["servos"][0]["max_velocity_dps"] = 45;
  config["servos"][0]["torque_limit_pct"] = 60;
  config["servos"][1]["invert"] = true;
  config["servos"][1]["offset_deg"] = 10;
  rig.make(config);
  rig.driver->start();
  CHECK(rig.emulator.servo(1).u16(sts::kTorqueLimit) == 600);
  rig.driver->set_joint_targets({{"j1", 90.0, 400.0}, {"j2", 40.0, 0.0}});
  CHECK(rig.emulator.servo(1).u16(sts::kGoalSpeed) == 512);  // held at start at the default speed, capped
  REQUIRE(rig.emulator.wait_until([](const StsServos& s) { return s.at(1).signed16(sts::kGoalPosition) == 2048 + 1024; }, 2s));
  CHECK(rig.emulator.servo(1).u16(sts::kGoalSpeed) == 512);  // capped at 45 deg/s whatever was asked
  CHECK(rig.emulator.servo(1).u16(sts::kTorqueLimit) == 600);
  CHECK(rig.emulator.servo(2).signed16(sts::kGoalPosition) == 2048 - 341);  // (40 - 10) deg the other way
  CHECK(feetech_error_of([&] {
          rig.driver->set_joint_targets({{"j4", 100.0, 0.0}});
        }).find("outside the servo's range [-90") != std::string::npos);

  rig.driver->set_torque_limit("j3", 25);
  CHECK(rig.emulator.wait_until([](const StsServos& s) { return s.at(3).u16(sts::kTorqueLimit) == 250; }, 2s));
  CHECK(rig.emulator.servo(3).signed16(sts::kGoalPosition) == 2048);  // still holding
  CHECK_THROWS_AS(rig.driver->set_torque_limit("j3", 0), std::invalid_argument);
  CHECK_THROWS_AS(rig.driver->set_torque_limit("j9", 50), std::invalid_argument);
  CHECK(rig.driver->status()["servos"][2]["torque_limit_pct"] == 25.0);
}

TEST_CASE("feetech halt: one sync write for every servo; the arm holds where it is, torque on") {
  StsRig rig;
  rig.make(so_arm_config(rig.pty.slave_path()));
  rig.driver->start();
  rig.driver->set_joint_targets({{"j1", 90.0, 20.0}, {"j6", -90.0, 20.0}});  // slow moves: 228 steps/s
  REQUIRE(rig.emulator.wait_until([](const StsServos& s) { return s.at(1).signed16(sts::kPresentPosition) > 2048 + 100; }, 3s));
  rig.emulator.clear_received();
  rig.driver->halt();
  CHECK(rig.driver->status()["halts_unconfirmed"] == 0);
  REQUIRE(rig.emulator.wait_until(all_still, 2s));
  const auto sent = rig.commands();
  REQUIRE(sent.size() == 1);
  CHECK(sent[0].code == inst::kSyncWrite);
  CHECK(sent[0].params[0] == sts::kGoalPosition);
  CHECK(sent[0].params.size() == 2 + 6 * 9);
  const auto j1 = rig.emulator.servo(1);
  CHECK(j1.u8(sts::kTorqueEnable) == 1);
  CHECK(j1.signed16(sts::kPresentPosition) > 2048 + 50);  // (held where the last poll saw it, give or take a tick)
  CHECK(j1.signed16(sts::kPresentPosition) < 3072 - 50);  // stopped on the way, nowhere near the target
  CHECK(j1.u16(sts::kGoalSpeed) != 0);                    // 0 would mean full speed in position mode
  const auto states = rig.driver->joint_states();
  CHECK(states[0].target_deg == doctest::Approx((j1.signed16(sts::kGoalPosition) - 2048) * 360.0 / 4096));
  CHECK(states[0].torque_on);
}

TEST_CASE("feetech halt does not wait behind a poll stuck on a silent servo") {
  StsRig rig;
  auto config = so_arm_config(rig.pty.slave_path());
  config["reply_timeout_ms"] = 400;  // a poll now waits 400 ms for the servo that no longer answers
  rig.make(config);
  rig.driver->start();
  rig.emulator.set_present(6, false);
  rig.emulator.clear_received();
  REQUIRE(rig.emulator.wait_for_packets([](const auto& received) { return !received.empty(); }, 2s));  // a poll is out
  const auto t0 = std::chrono::steady_clock::now();
  rig.driver->halt();
  const auto took = std::chrono::steady_clock::now() - t0;
  CHECK(took < 100ms);  // its deadline is 5 ms; a generous bound for a loaded CI machine
  CHECK(rig.driver->status()["halts_unconfirmed"] == 0);
  REQUIRE(rig.wait_for_command());
}

// A USB adapter that stops taking bytes: write() blocks until released (a hung bus).
class StallingLink final : public rcand::plugins::dynamixel::SerialLink {
 public:
  explicit StallingLink(std::shared_ptr<SerialLink> real) : real_(std::move(real)) {}
  void write(std::span<const std::uint8_t> bytes, Clock::time_point until) override {
    {
      std::unique_lock lock(mutex_);
      if (stalled_) {
        blocked_ = true;
        changed_.notify_all();
        changed_.wait(lock, [&] { return !stalled_; });
      }
    }
    real_->write(bytes, until);
  }
  std::size_t read_some(std::span<std::uint8_t> out, Clock::time_point until) override { return real_->read_some(out, until); }
  void discard_input() override { real_->discard_input(); }
  void interrupt() noexcept override { real_->interrupt(); }
  void clear_interrupt() noexcept override { real_->clear_interrupt(); }
  std::string path() const override { return real_->path(); }
  int baud_rate() const override { return real_->baud_rate(); }

  void stall() {
    std::lock_guard lock(mutex_);
    stalled_ = true;
  }
  bool wait_blocked() {
    std::unique_lock lock(mutex_);
    return changed_.wait_for(lock, 2s, [&] { return blocked_; });
  }
  void release() {
    std::lock_guard lock(mutex_);
    stalled_ = false;
    changed_.notify_all();
  }

 private:
  std::shared_ptr<SerialLink> real_;
  std::mutex mutex_;
  std::condition_variable changed_;
  bool stalled_ = false, blocked_ = false;
};

TEST_CASE("feetech halt meets its deadline on a hung bus, and says it was not confirmed") {
  PtyPair pty;
  StsEmulator emulator(pty.master(), {1, 2});
  json config{{"port", pty.slave_path()},
              {"servos", {{{"id", 1}, {"joint", "a"}}, {{"id", 2}, {"joint", "b"}}}},
              {"reply_timeout_ms", 50}};
  auto link = std::make_shared<StallingLink>(std::make_shared<PosixSerial>(pty.slave_path(), 1000000));
  FeetechDriver driver(FeetechSettings::from(rcand::sdk::ConfigView(config)), link);
  driver.start();
  link->stall();
  REQUIRE(link->wait_blocked());  // the next poll's write hangs in the adapter
  const auto t0 = std::chrono::steady_clock::now();
  driver.halt();
  const auto took = std::chrono::steady_clock::now() - t0;
  CHECK(took < 100ms);  // its deadline is 5 ms; a generous bound for a loaded CI machine
  const auto status = driver.status();
  CHECK(status["halts_unconfirmed"] == 1);
  CHECK(status["last_error"].get<std::string>().find("halt not written within 5 ms (adapter stalled?)") == 0);
  link->release();
}

TEST_CASE("feetech wheels: wheel mode, speeds with invert, halt stops them in one sync write") {
  StsRig rig({7, 8});
  rig.make(wheel_config(rig.pty.slave_path()));
  rig.driver->start();
  CHECK(rig.driver->interface_name() == "differential_drive");
  CHECK(rig.emulator.servo(7).u8(sts::kOperatingMode) == sts::kModeWheel);
  CHECK(rig.emulator.servo(8).u8(sts::kOperatingMode) == sts::kModeWheel);
  CHECK(rig.emulator.servo(7).u8(sts::kLock) == 1);
  CHECK(rig.logged("the wheels keep turning at their last speed"));
  CHECK(rig.driver->fail_safe().find("WHEELS KEEP TURNING") != std::string::npos);
  rig.driver->set_wheel_speeds(0.5, 0.5);
  REQUIRE(rig.emulator.wait_until([](const StsServos& s) { return s.at(7).signed16(sts::kPresentSpeed) == 1536; }, 2s));
  CHECK(rig.emulator.servo(8).signed16(sts::kGoalSpeed) == -1536);  // mirrored motor
  rig.emulator.clear_received();
  rig.driver->halt();
  REQUIRE(rig.emulator.wait_until(all_still, 2s));
  const auto sent = rig.commands();
  REQUIRE(sent.size() == 1);
  CHECK(sent[0].code == inst::kSyncWrite);
  CHECK(rig.emulator.servo(7).u8(sts::kTorqueEnable) == 1);
  CHECK(rig.emulator.servo(7).u16(sts::kGoalSpeed) == 0);
  CHECK(rig.emulator.servo(8).u16(sts::kGoalSpeed) == 0);
}

TEST_CASE("feetech: a missing servo at start and a servo lost at run time are named faults (its id and the port)") {
  {
    StsRig rig({1, 2, 3, 4, 5});
    rig.make(so_arm_config(rig.pty.slave_path()));
    const auto error = feetech_error_of([&] { rig.driver->start(); });
    CHECK(error.find("Feetech servo ID 6 (j6) on " + rig.pty.slave_path() +
                     " is missing: no answer from Feetech servo ID 6 (ping, 3 tries)") == 0);
  }
  StsRig rig;
  rig.make(so_arm_config(rig.pty.slave_path()));
  rig.driver->start();
  rig.emulator.set_present(4, false);
  // The emulator wakes every millisecond; the driver's mutex is never held while it waits for the emulator.
  const auto faulted = [&](const StsServos&) { return rig.driver->status().contains("fault"); };
  REQUIRE(rig.emulator.wait_until(faulted, 5s));
  const json status = rig.driver->status();
  REQUIRE(status.contains("fault"));
  CHECK(status["fault"] == "Feetech servo ID 4 (j4) on " + rig.pty.slave_path() + " lost: no answer to its status reads");
  CHECK(status["servos"][3]["lost"] == true);
  CHECK(status["servos"][3]["position_deg"].is_null());  // unknown, never a stale guess
  CHECK(rig.logged("Feetech servo ID 4 (j4) on " + rig.pty.slave_path() + " lost: no answer to 3 status reads in a row"));
  rig.emulator.set_present(4, true);
  CHECK(rig.emulator.wait_until([&](const StsServos& s) { return !faulted(s); }, 5s));
  CHECK(rig.logged("Feetech servo ID 4 (j4) on " + rig.pty.slave_path() + " answers again"));
  CHECK_FALSE(rig.driver->status().contains("fault"));
}

TEST_CASE("feetech: the model each servo reports is checked") {
  PtyPair pty;
  StsEmulator scs(pty.master(), {1}, 1284);  // an SCS0009
  json config{{"port", pty.slave_path()}, {"servos", {{{"id", 1}, {"joint", "a"}}}}, {"reply_timeout_ms", 50}};
  FeetechDriver driver(FeetechSettings::from(rcand::sdk::ConfigView(config)),
                       std::make_shared<PosixSerial>(pty.slave_path(), 1000000));
  CHECK(feetech_error_of([&] { driver.start(); }).find("is model number 1284, which this driver does not know") !=
        std::string::npos);
}

TEST_CASE("feetech plugin: loads against its manifest, reached through the motion gate; a missing port is a named fault") {
  PtyPair pty;
  StsEmulator emulator(pty.master(), {1, 2});
  rcand::sdk::testing::FakeHost host;
  std::ifstream in(RCAND_SOURCE_DIR "/manifests/feetech.json");
  host.load(RCAND_ENTRY_FUNCTION, json::parse(in));
  json config{{"port", "/dev/ttyACM-rcand-none"},
              {"servos", {{{"id", 1}, {"joint", "j1"}}, {{"id", 2}, {"joint", "j2"}}}},
              {"reply_timeout_ms", 50}};
  CHECK_THROWS_WITH_AS(host.add_driver("arm0", "feetech", config), doctest::Contains("cannot open /dev/ttyACM-rcand-none"),
                       rcand::sdk::testing::HostError);
  config["port"] = pty.slave_path();
  host.add_driver("arm0", "feetech", config);
  CHECK(host.motion().first_actuator("joint_arm") == "arm0");
  REQUIRE(host.motion().actuate_as<rcand::sdk::JointArm>("arm0", [](auto& arm) {
    arm.set_joint_targets({{"j2", 30.0, 0.0}});
  }) == rcand::sdk::GateStatus::Ok);
  CHECK(emulator.wait_until([](const StsServos& s) { return s.at(2).signed16(sts::kGoalPosition) == 2048 + 341; }, 2s));
  host.latch_estop("test");
  CHECK(host.motion().actuate_as<rcand::sdk::JointArm>("arm0", [](auto& arm) {
    arm.set_joint_targets({{"j2", 0.0, 0.0}});
  }) == rcand::sdk::GateStatus::EstopActive);
  CHECK(emulator.servo(2).u8(sts::kTorqueEnable) == 1);  // the e-stop holds the arm; it does not drop it
}
