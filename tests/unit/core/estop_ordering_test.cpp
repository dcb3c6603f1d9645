// The stop's ordering guarantee (Estop::latch): once latch() returns, no command reaches a driver, and every
// driver's last call is a halt, also for a command that was already inside the motion gate when the latch landed.
#include <doctest/doctest.h>

#include <atomic>
#include <future>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "kernel/safety/estop.hpp"
#include "kernel/safety/kernel_motion_gate.hpp"
#include "libs/base/deadline_crew.hpp"
#include "libs/base/steady_clock.hpp"

using namespace rcand;
using namespace rcand::kernel;
using rcand::sdk::GateStatus;

namespace {

// Every call the driver sees, in order, plus what the test itself notes ("latch returned").
class OrderingEventLog {
 public:
  void add(std::string event) {
    std::lock_guard lock(mutex_);
    events_.push_back(std::move(event));
  }
  std::vector<std::string> events() const {
    std::lock_guard lock(mutex_);
    return events_;
  }

 private:
  mutable std::mutex mutex_;
  std::vector<std::string> events_;
};

// A drive whose command blocks inside the gate until the test releases it (a slow bus write).
class BlockingOrderingDrive final : public rcand::sdk::DifferentialDrive {
 public:
  explicit BlockingOrderingDrive(OrderingEventLog& log) : log_(log) {}
  void set_wheel_speeds(double left, double) override {
    if (block_next.exchange(false)) {
      entered.set_value();
      release.get_future().wait();
    }
    speed.store(left);
    log_.add("command");
  }
  void halt() noexcept override {
    speed.store(0);
    log_.add("halt");
  }
  std::atomic<bool> block_next{false};
  std::promise<void> entered, release;
  std::atomic<double> speed{0};

 private:
  OrderingEventLog& log_;
};

// A drive whose command takes a little while (widens the race window), counting calls without locks.
class SlowOrderingDrive final : public rcand::sdk::DifferentialDrive {
 public:
  void set_wheel_speeds(double left, double) override {
    const auto until = std::chrono::steady_clock::now() + std::chrono::microseconds(30);
    while (std::chrono::steady_clock::now() < until) {
    }
    speed.store(left);
    commands.fetch_add(1);
    last_was_halt.store(false);
  }
  void halt() noexcept override {
    speed.store(0);
    last_was_halt.store(true);
  }
  std::atomic<double> speed{0};
  std::atomic<int> commands{0};
  std::atomic<bool> last_was_halt{true};
};

}  // namespace

TEST_CASE("latch() returns only after a command already inside the gate has left it, halted after it") {
  SteadyClock clock;
  ActuatorTable table;
  Estop estop{clock, table};
  KernelMotionGate gate{table, estop};
  OrderingEventLog log;
  BlockingOrderingDrive drive(log);
  InstanceHealth health;
  table.add("drive0", "differential_drive", "org.test", &drive, &health);

  drive.block_next = true;
  auto entered = drive.entered.get_future();
  std::promise<GateStatus> command_status;
  std::thread commander([&] {
    command_status.set_value(
        gate.actuate_as<rcand::sdk::DifferentialDrive>("drive0", [](auto& d) { d.set_wheel_speeds(0.8, 0.8); }));
  });
  entered.wait();  // the command is past the gate's latch check, inside the driver

  std::atomic<bool> latch_returned{false};
  Estop::StopReport report;
  std::thread stopper([&] {
    report = estop.latch("ordering", "unit");
    log.add("latch returned");
    latch_returned = true;
  });
  // Release the command once the stop either returned (the old behaviour: the test then fails on the order) or
  // waits for the command to leave the gate. Both are events the stop thread publishes; no timing involved.
  while (!latch_returned.load() && table.stops_waiting() == 0) std::this_thread::yield();
  drive.release.set_value();
  stopper.join();
  commander.join();

  const auto events = log.events();
  // The stop's own halt, then the command that was in flight, then the gate's halt, and only then latch() returns.
  REQUIRE(events == std::vector<std::string>{"halt", "command", "halt", "latch returned"});
  CHECK(command_status.get_future().get() == GateStatus::EstopActive);
  CHECK(report.commands_in_flight.empty());
  REQUIRE(report.drivers.size() == 1);
  CHECK(report.drivers[0].halted);
  CHECK(drive.speed == 0.0);

  // Latched: a new command never reaches the driver.
  CHECK(gate.actuate_as<rcand::sdk::DifferentialDrive>("drive0", [](auto& d) { d.set_wheel_speeds(0.5, 0.5); }) ==
        GateStatus::EstopActive);
  CHECK(log.events().size() == events.size());
}

TEST_CASE("a command that never leaves the gate is named in the stop report at the deadline") {
  SteadyClock clock;
  ActuatorTable table;
  Estop estop{clock, table};
  KernelMotionGate gate{table, estop};
  OrderingEventLog log;
  BlockingOrderingDrive drive(log);
  InstanceHealth health;
  table.add("drive0", "differential_drive", "org.test", &drive, &health);

  drive.block_next = true;
  auto entered = drive.entered.get_future();
  std::thread commander(
      [&] { gate.actuate_as<rcand::sdk::DifferentialDrive>("drive0", [](auto& d) { d.set_wheel_speeds(0.8, 0.8); }); });
  entered.wait();
  const auto started = std::chrono::steady_clock::now();
  const auto report = estop.latch("stuck command", "unit");
  const auto took = std::chrono::steady_clock::now() - started;
  drive.release.set_value();
  commander.join();

  CHECK(took >= Estop::kHaltDeadline);
  CHECK(took < std::chrono::milliseconds(500));  // bounded: the stop answers whatever the driver does
  CHECK(report.commands_in_flight == std::vector<std::string>{"drive0"});
  REQUIRE(report.drivers.size() == 1);
  CHECK_FALSE(report.drivers[0].halted);
  CHECK(report.drivers[0].state == "command_in_flight");
  CHECK(report.drivers[0].error.find("motion gate") != std::string::npos);
  CHECK(log.events().back() == "halt");  // the gate halted it when the command finally returned
}

TEST_CASE("a stop requested from inside a command does not wait for that command") {
  SteadyClock clock;
  ActuatorTable table;
  Estop estop{clock, table};
  KernelMotionGate gate{table, estop};
  SlowOrderingDrive drive;
  InstanceHealth health;
  table.add("drive0", "differential_drive", "org.test", &drive, &health);
  Estop::StopReport report;
  const auto started = std::chrono::steady_clock::now();
  const auto status = gate.actuate_as<rcand::sdk::DifferentialDrive>("drive0", [&](auto& d) {
    d.set_wheel_speeds(0.4, 0.4);
    report = estop.latch("from inside", "unit");
  });
  CHECK(std::chrono::steady_clock::now() - started < Estop::kHaltDeadline);
  CHECK(status == GateStatus::EstopActive);
  CHECK(report.commands_in_flight.empty());
  CHECK(drive.speed == 0.0);
}

TEST_CASE("race: no command reaches the driver after latch() returned, and the driver's last call is a halt") {
  // Two commanders hammer the gate while the stop latches, with the halts on the crew as in the kernel. The old
  // gate let a command that was inside when the latch landed reach the driver after latch() returned.
  constexpr int kRounds = 600;
  int late_commands = 0;
  for (int round = 0; round < kRounds; ++round) {
    SteadyClock clock;
    ActuatorTable table;
    Estop estop{clock, table};
    KernelMotionGate gate{table, estop};
    SlowOrderingDrive drive;
    InstanceHealth health;
    table.add("drive0", "differential_drive", "org.test", &drive, &health);
    DeadlineCrew crew("test.halt", {{"drive0", [&drive] { drive.halt(); }}});
    estop.use_halt_crew(&crew);

    std::atomic<int> ready{0};
    std::atomic<bool> go{false};
    auto hammer = [&] {
      ready.fetch_add(1);
      while (!go.load()) {
      }
      for (int i = 0; i < 400; ++i)
        if (gate.actuate_as<rcand::sdk::DifferentialDrive>("drive0", [](auto& d) { d.set_wheel_speeds(1.0, 1.0); }) ==
            GateStatus::EstopActive)
          break;
    };
    std::thread a(hammer), b(hammer);
    while (ready.load() < 2) std::this_thread::yield();
    go = true;
    // Let the commanders get going (a few commands each) so the latch lands while one is inside the gate.
    while (drive.commands.load() < 2 + round % 5) {
    }
    estop.latch("race", "unit");
    const int at_return = drive.commands.load();
    const double speed_at_return = drive.speed.load();
    a.join();
    b.join();
    estop.use_halt_crew(nullptr);
    if (drive.commands.load() != at_return) ++late_commands;
    REQUIRE(speed_at_return == 0.0);
    REQUIRE(drive.last_was_halt.load());
    REQUIRE(drive.speed.load() == 0.0);
  }
  CHECK(late_commands == 0);
}
