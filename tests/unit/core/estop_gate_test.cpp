#include <doctest/doctest.h>

#include <atomic>
#include <stdexcept>
#include <thread>

#include "kernel/safety/estop.hpp"
#include "kernel/safety/kernel_motion_gate.hpp"
#include "libs/base/steady_clock.hpp"

using namespace rcand;
using namespace rcand::kernel;
using rcand::sdk::GateStatus;

namespace {

// A drive whose speed is one atomic: halt() and set never wait on each other, like a real driver's register write.
class TestDrive final : public rcand::sdk::DifferentialDrive {
 public:
  void set_wheel_speeds(double left, double) override {
    if (throw_next) throw std::runtime_error("bus fault");
    speed.store(left);
    ++commands;
  }
  void halt() noexcept override {
    speed.store(0);
    ++halts;
  }
  std::atomic<double> speed{0};
  std::atomic<int> commands{0}, halts{0};
  bool throw_next = false;
};

struct Rig {
  SteadyClock clock;
  ActuatorTable table;
  Estop estop{clock, table};
  KernelMotionGate gate{table, estop};
  TestDrive drive;
  InstanceHealth health;
  Rig() { table.add("drive0", "differential_drive", "org.test", &drive, &health); }
  GateStatus go(double speed) {
    return gate.actuate_as<rcand::sdk::DifferentialDrive>("drive0", [&](auto& d) { d.set_wheel_speeds(speed, speed); });
  }
};

}  // namespace

TEST_CASE("the gate passes commands while unlatched and refuses them while latched") {
  Rig rig;
  CHECK(rig.go(0.5) == GateStatus::Ok);
  CHECK(rig.drive.speed == 0.5);
  const auto report = rig.estop.latch("test", "unit");
  CHECK(report.newly_latched);
  CHECK(report.drivers.size() == 1);
  CHECK(report.drivers[0].halted);
  CHECK(rig.drive.speed == 0);
  const int before = rig.drive.commands;
  CHECK(rig.go(0.7) == GateStatus::EstopActive);
  CHECK(rig.drive.commands == before);  // the driver received nothing
  CHECK(rig.drive.speed == 0);
  CHECK(rig.estop.clear());
  CHECK(rig.go(0.3) == GateStatus::Ok);
}

TEST_CASE("a repeated stop re-halts but keeps the first reason") {
  Rig rig;
  rig.estop.latch("first", "alice");
  const auto second = rig.estop.latch("second", "bob");
  CHECK_FALSE(second.newly_latched);
  CHECK(rig.drive.halts == 2);
  const auto snapshot = rig.estop.snapshot();
  CHECK(snapshot.estopped);
  CHECK(snapshot.reason == "first");
  CHECK(snapshot.source == "alice");
  CHECK(snapshot.since_ms > 0);
}

TEST_CASE("unknown, wrong-interface and failing actuators") {
  Rig rig;
  CHECK(rig.gate.actuate("nope", [](auto&) {}) == GateStatus::UnknownActuator);
  CHECK(rig.gate.first_actuator("differential_drive") == std::optional<std::string>("drive0"));
  CHECK_FALSE(rig.gate.first_actuator("gripper").has_value());
  rig.drive.throw_next = true;
  CHECK(rig.go(0.4) == GateStatus::ActuatorFailed);
  CHECK(rig.health.failed());
  CHECK(rig.health.reason() == "bus fault");
  CHECK(rig.drive.halts == 1);  // a throwing driver is halted
  rig.drive.throw_next = false;
  CHECK(rig.go(0.4) == GateStatus::ActuatorFailed);  // and stays out of service
}

TEST_CASE("a command racing a stop never leaves the motor running") {
  // The stop thread latches while the command thread hammers the gate; whatever the interleaving, once both are
  // done the motor is at zero.
  for (int round = 0; round < 300; ++round) {
    Rig rig;
    std::atomic<bool> go{false};
    std::thread commander([&] {
      while (!go.load()) {
      }
      for (int i = 0; i < 200; ++i)
        if (rig.go(1.0) == GateStatus::EstopActive) break;
    });
    go = true;
    rig.estop.latch("race", "unit");
    commander.join();
    REQUIRE(rig.drive.speed.load() == 0.0);
  }
}

TEST_CASE("sleep_unless_latched wakes on the latch, not at the end of the sleep") {
  Rig rig;
  CHECK(rig.estop.sleep_unless_latched(std::chrono::microseconds(1000)));  // unlatched: full sleep, true
  std::atomic<bool> woke_early{false};
  std::thread sleeper([&] { woke_early = !rig.estop.sleep_unless_latched(std::chrono::hours(1)); });
  rig.estop.latch("wake", "unit");
  sleeper.join();  // would hang for an hour if the latch did not wake it
  CHECK(woke_early);
}

TEST_CASE("listeners run on the stop path after the halt") {
  Rig rig;
  double speed_seen = -1;
  rig.go(0.9);
  rig.estop.on_latched([&] { speed_seen = rig.drive.speed; });
  rig.estop.latch("x", "unit");
  CHECK(speed_seen == 0.0);
}

TEST_CASE("POST /api/stop's two steps: halted and recorded before its answer, the listeners after it, once") {
  Rig rig;
  int listened = 0;
  rig.go(0.9);
  rig.estop.on_latched([&] { ++listened; });
  try {
    const Estop::Announcement latched{rig.estop, rig.estop.latch_unannounced("answered first", "unit")};
    CHECK(rig.drive.speed == 0.0);  // every actuator halted before the answer is built
    CHECK(latched.report.newly_latched);
    CHECK(rig.estop.snapshot().reason == "answered first");  // GET /api/estop right after the answer shows it
    CHECK(listened == 0);
    throw std::runtime_error("building the answer failed");
  } catch (const std::runtime_error&) {
  }
  CHECK(listened == 1);  // announced all the same: the latch record and telemetry follow every latch
  rig.estop.latch("again", "unit");
  CHECK(listened == 2);
}

TEST_CASE("a command overtaken by a stop that was already cleared is still halted") {
  Rig rig;
  const auto status = rig.gate.actuate_as<rcand::sdk::DifferentialDrive>("drive0", [&](auto& d) {
    rig.estop.latch("mid-command", "unit");  // a stop arrives while the command runs...
    rig.estop.clear();                       // ...and is cleared before it returns
    d.set_wheel_speeds(0.8, 0.8);
  });
  CHECK(status == GateStatus::EstopActive);
  CHECK(rig.drive.speed == 0.0);
}

TEST_CASE("a plugin reload retires a driver: halts and the gate skip it, and it is destroyed only once no call uses it") {
  Rig rig;
  ActuatorSlot& slot = *rig.table.find("drive0");
  rig.estop.latch("plugin reload", "unit");
  const int halts_before = rig.drive.halts;
  {
    const DriverUse in_use(slot);  // a call into the old driver, still running
    CHECK_FALSE(ActuatorTable::retire(slot, std::chrono::steady_clock::now() + std::chrono::milliseconds(20)));
  }
  CHECK(ActuatorTable::retire(slot, std::chrono::steady_clock::now() + std::chrono::seconds(5)));
  CHECK(rig.estop.clear());
  CHECK(rig.go(0.4) == GateStatus::ActuatorFailed);  // out of service while its plugin reloads
  rig.gate.halt("drive0");
  rig.estop.latch("again", "unit");
  CHECK(rig.drive.halts == halts_before);  // nothing reached the retired object
  CHECK(rig.estop.clear());

  TestDrive replacement;  // the new version's object, back in the same slot
  ActuatorTable::install(slot, &replacement);
  CHECK(rig.go(0.4) == GateStatus::Ok);
  CHECK(replacement.speed == 0.4);
  CHECK(rig.drive.commands == 0);
  rig.estop.latch("after the reload", "unit");
  CHECK(replacement.speed == 0);
}

TEST_CASE("retire waits for a command in the gate to return before it reports the driver free") {
  Rig rig;
  ActuatorSlot& slot = *rig.table.find("drive0");
  std::atomic<bool> entered{false}, release{false};
  std::thread command([&] {
    rig.gate.actuate("drive0", [&](auto&) {
      entered = true;
      entered.notify_all();
      release.wait(false);
    });
  });
  entered.wait(false);
  std::atomic<bool> retired{false};
  std::thread reload([&] {
    retired = ActuatorTable::retire(slot, std::chrono::steady_clock::now() + std::chrono::seconds(30));
    retired.notify_all();
  });
  while (slot.driver.load() != nullptr) std::this_thread::yield();  // the reload has taken it out of the slot
  CHECK_FALSE(retired);                                             // but the command still runs in it
  release = true;
  release.notify_all();
  command.join();
  reload.join();
  CHECK(retired);
  CHECK(slot.users.load() == 0);
}
