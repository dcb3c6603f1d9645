// The fake host itself: descriptor checks, routing with scope and e-stop checks, the motion gate's race rule,
// the deterministic workers and clock. sim_drive is the real driver behind the gate; a small probe plugin,
// declared here as the nav capability, provides routes of every kind.
#include <doctest/doctest.h>

#include <rcand/sdk/interfaces/pose_source.hpp>
#include <rcand/sdk/interfaces/trip_estimator.hpp>
#include <rcand/sdk/plugin.hpp>
#include <rcand/sdk/testing/fake_host.hpp>
#include <rcand/sdk/testing/recording_drive.hpp>

#include <chrono>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "sim_drive.hpp"

extern "C" const rcand_plugin_descriptor* RCAND_ENTRY_FUNCTION(void);

using namespace std::chrono_literals;
using rcand::plugins::sim_drive::SimDrive;
using namespace rcand::sdk;
using rcand::sdk::testing::FakeHost;
using rcand::sdk::testing::HostError;
using rcand::sdk::testing::LoadError;
using rcand::sdk::testing::RecordingDrive;

namespace {

// ---- descriptors with one thing wrong each -----------------------------------------------------------------

rcand_plugin_descriptor tweaked(void (*tweak)(rcand_plugin_descriptor&)) {
  rcand_plugin_descriptor d = *RCAND_ENTRY_FUNCTION();
  tweak(d);
  return d;
}
const rcand_plugin_descriptor* bad_magic() {
  static const auto d = tweaked([](rcand_plugin_descriptor& x) { x.magic = 0xdeadbeef; });
  return &d;
}
const rcand_plugin_descriptor* abi_major_2() {
  static const auto d = tweaked([](rcand_plugin_descriptor& x) { x.abi_major = 2; });
  return &d;
}
const rcand_plugin_descriptor* abi_minor_newer() {
  static const auto d = tweaked([](rcand_plugin_descriptor& x) { x.abi_minor = RCAND_ABI_MINOR + 1; });
  return &d;
}
const rcand_plugin_descriptor* abi_minor_previous() {  // built against the minor before the host's
  static const auto d = tweaked([](rcand_plugin_descriptor& x) { x.abi_minor = RCAND_ABI_MINOR - 1; });
  return &d;
}
const rcand_plugin_descriptor* too_large() {
  static const auto d = tweaked([](rcand_plugin_descriptor& x) { x.struct_size += 8; });
  return &d;
}
const rcand_plugin_descriptor* too_small() {
  static const auto d = tweaked([](rcand_plugin_descriptor& x) { x.struct_size = 8; });
  return &d;
}
const rcand_plugin_descriptor* no_descriptor() { return nullptr; }
const rcand_plugin_descriptor* throwing_register() {
  static const auto d = tweaked([](rcand_plugin_descriptor& x) {
    x.plugin_id = "org.test.throws";
    x.register_plugin = [](rcand_registrar*) { throw std::runtime_error("cannot register today"); };
  });
  return &d;
}

// ---- a probe plugin with routes of every kind --------------------------------------------------------------

struct ProbeState {
  int motion_calls = 0;
  int estops = 0;
  bool throw_next = false;
};
ProbeState probe;

class Probe final : public Capability {
 public:
  explicit Probe(PluginContext& ctx) : ctx_(ctx) {}
  std::vector<Route> routes() override {
    return {
        {"GET", "/api/nav/probe", Scope::Status, false, "",
         [](const Request&) {
           return Response::ok({{"probe", true}});
         }},
        {"POST", "/api/nav/probe/config", Scope::Config, false, "", [](const Request&) { return Response::ok(); }},
        {"POST", "/api/nav/probe/move", Scope::Control, true, "",
         [this](const Request& req) {
           ++probe.motion_calls;
           if (probe.throw_next) throw std::runtime_error("probe exploded");
           const double speed = req.body.value("speed", 0.5);
           const auto status = ctx_.motion().actuate_as<DifferentialDrive>(
               "base", [&](DifferentialDrive& d) { d.set_wheel_speeds(speed, speed); });
           if (status != GateStatus::Ok) return gate_refusal(status, "base");
           return Response::ok({{"role", std::string(role_name(req.role))}});
         }},
    };
  }
  void on_estop() noexcept override { ++probe.estops; }

 private:
  PluginContext& ctx_;
};

class Custom final : public Capability {
 public:
  std::vector<Route> routes() override {
    return {{"GET", "/ping", Scope::Status, false, "",
             [](const Request& req) { return Response::ok({{"subpath", req.subpath}, {"q", req.query.at("q")}}); }}};
  }
};

void register_probe(Registrar& r) {
  r.add_capability({"nav", true}, [](PluginContext& ctx) { return std::make_unique<Probe>(ctx); });
  r.add_capability({"org.test.custom", false}, [](PluginContext&) { return std::make_unique<Custom>(); });
}
const rcand_plugin_descriptor* probe_entry() {
  static const rcand_plugin_descriptor d{sizeof(rcand_plugin_descriptor), RCAND_DESCRIPTOR_MAGIC, RCAND_ABI_MAJOR,
                                         RCAND_ABI_MINOR, "org.test.probe", "0.0.1", "test",
                                         [](rcand_registrar* r) { register_probe(*reinterpret_cast<Registrar*>(r)); }};
  return &d;
}

// A host with sim_drive as "base" and the probe plugin.
struct Fixture {
  FakeHost host;
  Fixture() {
    probe = {};
    host.load(RCAND_ENTRY_FUNCTION);
    host.load(probe_entry);
    host.add_driver("base", "sim_diff_drive");
    host.add_capability("nav");
    host.add_capability("org.test.custom");
  }
  SimDrive& sim() { return host.driver<SimDrive>("base"); }
  Response move(Role role = Role::Owner) { return host.call("POST", "/api/nav/probe/move", nlohmann::json::object(), role); }
};

}  // namespace

TEST_CASE("load checks the descriptor like the kernel") {
  FakeHost host;
  CHECK_THROWS_WITH_AS(host.load(bad_magic), doctest::Contains("magic"), LoadError);
  CHECK_THROWS_WITH_AS(host.load(abi_major_2), doctest::Contains("built for ABI 2, host speaks 1"), LoadError);
  CHECK_THROWS_WITH_AS(host.load(abi_minor_newer), doctest::Contains("newer than the host's"), LoadError);
  CHECK_THROWS_WITH_AS(host.load(too_large), doctest::Contains("larger than this host's"), LoadError);
  CHECK_THROWS_WITH_AS(host.load(too_small), doctest::Contains("smaller than the ABI 1.0 layout"), LoadError);
  CHECK_THROWS_WITH_AS(host.load(no_descriptor), doctest::Contains("no descriptor"), LoadError);
  CHECK_THROWS_WITH_AS(host.load(throwing_register), doctest::Contains("registration-failed"), LoadError);
  // None of the refused plugins registered anything; the good one still loads, once.
  CHECK_THROWS_AS(host.add_driver("base", "sim_diff_drive"), HostError);
  host.load(RCAND_ENTRY_FUNCTION);
  CHECK_THROWS_WITH_AS(host.load(RCAND_ENTRY_FUNCTION), doctest::Contains("duplicate plugin id"), LoadError);
  CHECK_NOTHROW(host.add_driver("base", "sim_diff_drive"));
  CHECK_THROWS_WITH_AS(host.add_driver("base", "sim_diff_drive"), doctest::Contains("already in use"), HostError);
}

TEST_CASE("load with a manifest refuses a mismatch between provides and registration") {
  const nlohmann::json good = {
      {"id", "org.rcand.sim_drive"},
      {"version", "0.1.0"},
      {"provides", {{{"kind", "driver"}, {"name", "sim_diff_drive"}, {"actuates", true}, {"interface", "differential_drive"}}}}};
  CHECK_NOTHROW(FakeHost().load(RCAND_ENTRY_FUNCTION, good));

  auto not_actuating = good;
  not_actuating["provides"][0]["actuates"] = false;
  CHECK_THROWS_WITH_AS(FakeHost().load(RCAND_ENTRY_FUNCTION, not_actuating), doctest::Contains("manifest-mismatch"), LoadError);
  auto extra = good;
  extra["provides"].push_back({{"kind", "capability"}, {"name", "teleop"}, {"actuates", true}});
  CHECK_THROWS_WITH_AS(FakeHost().load(RCAND_ENTRY_FUNCTION, extra), doctest::Contains("manifest-mismatch"), LoadError);
  auto other_version = good;
  other_version["version"] = "9.9.9";
  CHECK_THROWS_WITH_AS(FakeHost().load(RCAND_ENTRY_FUNCTION, other_version), doctest::Contains("version"), LoadError);
}

TEST_CASE("routes: scope check gives 403 INSUFFICIENT_PRIVILEGES before the handler runs") {
  Fixture f;
  const auto guest = f.move(Role::Guest);
  CHECK(guest.status == 403);
  CHECK(guest.body["code"] == "INSUFFICIENT_PRIVILEGES");
  CHECK(probe.motion_calls == 0);
  CHECK(f.move(Role::User).status == 200);
  CHECK(probe.motion_calls == 1);

  CHECK(f.host.call("GET", "/api/nav/probe", {}, Role::Guest).status == 200);
  CHECK(f.host.call("POST", "/api/nav/probe/config", {}, Role::Leasee).status == 403);
  CHECK(f.host.call("POST", "/api/nav/probe/config", {}, Role::Owner).status == 200);

  // A custom capability's Status route is raised to Control (§9.4).
  CHECK(f.host.call("GET", "/api/cap/org.test.custom/ping", {}, Role::Guest).status == 403);
  const auto custom = f.host.call("GET", "/api/cap/org.test.custom/ping?q=1", {}, Role::User);
  CHECK(custom.status == 200);
  CHECK(custom.body["subpath"] == "/ping");
  CHECK(custom.body["q"] == "1");
}

TEST_CASE("routes: unknown things answer 404, a bad action body 400") {
  Fixture f;
  CHECK(f.host.call("GET", "/api/nothing").status == 404);
  CHECK(f.host.call("GET", "/api/cap/com.nobody.thing/x").body["code"] == "CAPABILITY_NOT_FOUND");
  CHECK(f.host.call("GET", "/api/cap/org.test.custom/nope").body["code"] == "NOT_FOUND");
  const auto unknown_type = f.host.call("POST", "/api/action", {{"type", "dance"}});
  CHECK(unknown_type.status == 400);  // as the kernel answers it (rcand/sdk/contract/requests.hpp)
  CHECK(unknown_type.body["field"] == "type");
  CHECK(unknown_type.body["allowed"] == nlohmann::json::array());  // no capability serving /api/action is declared
  const auto no_type = f.host.call("POST", "/api/action", {{"linear", 1}});
  CHECK(no_type.status == 400);
  CHECK(no_type.body["field"] == "type");
}

TEST_CASE("a motion route while latched: 423 ESTOP_ACTIVE, handler not called, driver receives nothing") {
  Fixture f;
  f.host.latch_estop("test");
  CHECK(probe.estops == 1);
  const auto before = f.sim().timeline().size();
  const auto r = f.move();
  CHECK(r.status == 423);
  CHECK(r.body["code"] == "ESTOP_ACTIVE");
  CHECK(r.body["status"] == 423);
  CHECK(probe.motion_calls == 0);
  CHECK(f.sim().timeline().size() == before);
  CHECK(f.sim().commands() == 0);
  // Non-motion routes still answer; after clearing, motion works again.
  CHECK(f.host.call("GET", "/api/nav/probe", {}, Role::Guest).status == 200);
  f.host.clear_estop();
  CHECK(f.move().status == 200);
  CHECK(f.sim().left() == 0.5);
}

TEST_CASE("the gate refuses while latched even when called directly, and halt is always allowed") {
  Fixture f;
  f.host.latch_estop("test");
  bool ran = false;
  CHECK(f.host.motion().actuate("base", [&](ActuatorDriver&) { ran = true; }) == GateStatus::EstopActive);
  CHECK_FALSE(ran);
  f.host.motion().halt("base");
  CHECK(f.sim().halts() == 2);  // the latch, then ours
  f.host.clear_estop();
  CHECK(f.host.motion().actuate("nope", [&](ActuatorDriver&) { ran = true; }) == GateStatus::UnknownActuator);
  CHECK(f.host.motion().actuate_as<RecordingDrive>("base", [&](RecordingDrive&) { ran = true; }) ==
        GateStatus::WrongInterface);
  CHECK_FALSE(ran);
}

TEST_CASE("a command racing a latch ends halted") {
  Fixture f;
  const auto status = f.host.motion().actuate_as<DifferentialDrive>("base", [&](DifferentialDrive& d) {
    f.host.latch_estop("obstacle");  // the stop path runs while the command is in flight...
    d.set_wheel_speeds(1.0, 1.0);    // ...and the command then undoes the halt
  });
  CHECK(status == GateStatus::EstopActive);  // as the kernel answers: overtaken by a stop
  CHECK(f.sim().left() == 0.0);
  CHECK(f.sim().right() == 0.0);
  const auto timeline = f.sim().timeline();
  REQUIRE(timeline.size() == 3);
  CHECK(timeline[0].cause == "halt");
  CHECK(timeline[1].cause == "command");
  CHECK(timeline[2].cause == "halt");
  // Also when the latch is cleared again before the command returns.
  f.host.clear_estop();
  f.host.motion().actuate_as<DifferentialDrive>("base", [&](DifferentialDrive& d) {
    f.host.latch_estop("blip");
    f.host.clear_estop();
    d.set_wheel_speeds(1.0, 1.0);
  });
  CHECK(f.sim().left() == 0.0);
}

TEST_CASE("a driver that throws is marked failed; the gate answers ActuatorFailed") {
  FakeHost host;
  auto& drive = host.add_driver_instance<RecordingDrive>("wheels", host.clock());
  drive.fail_next();
  auto cmd = [](DifferentialDrive& d) { d.set_wheel_speeds(0.2, 0.2); };
  CHECK(host.motion().actuate_as<DifferentialDrive>("wheels", cmd) == GateStatus::ActuatorFailed);
  CHECK(host.driver_failed("wheels"));
  CHECK(host.motion().actuate_as<DifferentialDrive>("wheels", cmd) == GateStatus::ActuatorFailed);
  CHECK(drive.commands().empty());
  CHECK(gate_refusal(GateStatus::ActuatorFailed, "wheels").status == 503);
  bool logged = false;
  for (const auto& line : host.log_lines()) logged |= line.find("'wheels' threw") != std::string::npos;
  CHECK(logged);
}

TEST_CASE("a plugin's request_estop latches, halts every actuator and calls on_estop") {
  Fixture f;
  REQUIRE(f.move().status == 200);
  f.host.context("nav").estop().request_estop("bumper");
  CHECK(f.host.estopped());
  CHECK(f.sim().left() == 0.0);
  CHECK(probe.estops == 1);
  bool logged = false;
  for (const auto& line : f.host.log_lines()) logged |= line == "[warn] kernel.fake_host: e-stop latched: bumper";
  CHECK(logged);
}

TEST_CASE("a handler that throws answers 500; the capability stays in service (as in rcand, docs/protocol.md §7.16)") {
  Fixture f;
  probe.throw_next = true;
  const auto r = f.move();
  CHECK(r.status == 500);
  CHECK(r.body["code"] == "INTERNAL");
  CHECK(std::string(r.body["error"]).find("exploded") == std::string::npos);  // messages stay in the log
  CHECK_FALSE(f.host.capability_failed("nav"));
  CHECK(f.host.handler_errors("nav") == 1);
  probe.throw_next = false;
  CHECK(f.move().status == 200);
}

TEST_CASE("workers: tasks and timers run in order, at their due time, only when the test says so") {
  FakeHost host;
  host.add_driver_instance<RecordingDrive>("wheels", host.clock());
  auto& ctx = host.context("wheels");
  auto& worker = ctx.worker("jobs");
  CHECK(worker.name() == "wheels.jobs");
  CHECK(&ctx.worker("jobs") == &worker);
  CHECK_THROWS_AS(ctx.worker(""), std::invalid_argument);
  CHECK_THROWS_AS(ctx.worker("a b"), std::invalid_argument);

  std::vector<std::string> ran;
  std::vector<std::int64_t> at;
  auto record = [&](std::string name) {
    return [&, name] {
      ran.push_back(name);
      at.push_back(host.now_us());
    };
  };
  worker.schedule(300us, record("t300"));
  const TimerId cancelled = worker.schedule(200us, record("t200"));
  worker.schedule(100us, [&, record] {
    ran.push_back("t100");
    at.push_back(host.now_us());
    worker.post(record("posted-by-t100"));
  });
  worker.post(record("p1"));
  worker.post(record("p2"));
  CHECK(ran.empty());  // nothing runs by itself

  CHECK(host.run_pending() == 2);
  CHECK(ran == std::vector<std::string>{"p1", "p2"});
  CHECK(worker.cancel(cancelled));
  CHECK_FALSE(worker.cancel(cancelled));
  host.advance(250us);
  CHECK(ran == std::vector<std::string>{"p1", "p2", "t100", "posted-by-t100"});
  CHECK(at[2] == 100);
  CHECK(at[3] == 100);
  CHECK(host.now_us() == 250);
  host.advance(1ms);
  CHECK(ran.back() == "t300");
  CHECK(at.back() == 300);
  CHECK(host.now_us() == 1250);
}

TEST_CASE("a plugin built for the previous ABI minor still loads") {
  FakeHost host;
  CHECK_NOTHROW(host.load(abi_minor_previous));
  CHECK_NOTHROW(host.add_driver("base", "sim_diff_drive"));
}

TEST_CASE("publish_status: the host records what each instance published, in order, from any thread") {
  FakeHost host;
  host.add_driver_instance<RecordingDrive>("wheels", host.clock());
  auto& ctx = host.context("wheels");
  CHECK_FALSE(host.last_published_status("wheels"));
  CHECK(host.published_statuses("wheels").empty());
  ctx.publish_status({{"moving", true}});
  std::thread([&ctx] { ctx.publish_status({{"moving", false}, {"from", "another thread"}}); }).join();
  const Json first{{"moving", true}}, second{{"moving", false}, {"from", "another thread"}};
  CHECK(host.published_statuses("wheels") == std::vector<Json>{first, second});
  CHECK(host.last_published_status("wheels") == second);
  CHECK_FALSE(host.last_published_status("nobody"));

  // The sim drive publishes through its context, from its status worker, when it starts moving.
  host.load(RCAND_ENTRY_FUNCTION);
  host.add_driver("base", "sim_diff_drive");
  REQUIRE(host.motion().actuate_as<DifferentialDrive>("base", [](DifferentialDrive& d) { d.set_wheel_speeds(0.5, 0.5); }) ==
          GateStatus::Ok);
  host.run_pending();
  REQUIRE(host.last_published_status("base"));
  CHECK((*host.last_published_status("base"))["moving"] == true);
}

TEST_CASE("workers: simulate_cancel_race makes cancel lose; a throwing task is recorded") {
  FakeHost host;
  host.add_driver_instance<RecordingDrive>("wheels", host.clock());
  auto& worker = host.context("wheels").worker("jobs");
  int runs = 0;
  const TimerId id = worker.schedule(10us, [&] { ++runs; });
  host.simulate_cancel_race(true);
  CHECK_FALSE(worker.cancel(id));
  host.advance(10us);
  CHECK(runs == 1);
  host.simulate_cancel_race(false);

  worker.post([] { throw std::runtime_error("task broke"); });
  host.run_pending();
  REQUIRE(host.task_failures().size() == 1);
  CHECK(host.task_failures()[0] == "wheels.jobs: task broke");
}

TEST_CASE("sleep_unless_latched advances the manual clock and stops early at a scheduled latch") {
  FakeHost host;
  auto& estop = host.estop();
  CHECK(estop.sleep_unless_latched(5ms));
  CHECK(host.now_us() == 5000);
  host.latch_estop_at(7000, "scheduled");
  CHECK_FALSE(estop.sleep_unless_latched(5ms));
  CHECK(host.now_us() == 7000);
  CHECK(host.estopped());
  CHECK_FALSE(estop.sleep_unless_latched(5ms));  // already latched: returns at once
  CHECK(host.now_us() == 7000);

  FakeHost other;
  other.latch_estop_at(1500, "later");
  other.advance(1ms);
  CHECK_FALSE(other.estopped());
  other.advance(1ms);
  CHECK(other.estopped());
  CHECK(other.now_us() == 2000);
}

TEST_CASE("capability settings come from runtime.capabilities.<name> unless given") {
  FakeHost host({{"runtime", {{"capabilities", {{"nav", {{"answer", 42}}}}}}}});
  host.load(probe_entry);
  host.add_capability("nav");
  CHECK(host.context("nav").config().get<int>("answer") == 42);
  CHECK(host.context("nav").robot_config().get<int>("runtime.capabilities.nav.answer") == 42);
  CHECK(host.context("nav").plugin_id() == "org.test.probe");
  CHECK(host.context("nav").instance_id() == "nav");
}

// ---- services (PluginContext::offer_service / service; rcand/sdk/services.hpp) ------------------------------------

namespace {

struct FakePose final : PoseSource {
  PoseReading read() const noexcept override { return {true, {1.0, 2.0, 45.0}, true}; }
};
struct FakeTrips final : TripEstimator {
  std::optional<double> trip_seconds(const Pose2d&, double, double, double) const noexcept override { return 12.5; }
};
struct FakeObstacles final : ObstacleSource {
  ObstacleReading obstacles() const noexcept override { return {true, 30, 30, 30, 30, 0}; }
};

// A hand-made driver that offers a TripEstimator through its context and notes, in its shutdown(), whether the
// service could still be found then.
struct OfferingDriver final : Driver, TripEstimator {
  explicit OfferingDriver(std::optional<bool>& found_at_shutdown) : found_at_shutdown(found_at_shutdown) {}
  std::optional<double> trip_seconds(const Pose2d&, double, double, double) const noexcept override { return 1.0; }
  void shutdown() noexcept override { found_at_shutdown = rcand::sdk::find<TripEstimator>(*ctx) != nullptr; }
  std::optional<bool>& found_at_shutdown;
  PluginContext* ctx = nullptr;
};

bool logged(const FakeHost& host, const std::string& text) {
  for (const auto& line : host.log_lines())
    if (line.find(text) != std::string::npos) return true;
  return false;
}

}  // namespace

TEST_CASE("services: a test offers a fake PoseSource that instances find; one provider per id, as in rcand") {
  FakeHost host;
  host.add_driver_instance<RecordingDrive>("wheels", host.clock());
  host.add_driver_instance<RecordingDrive>("arm", host.clock());
  PluginContext& wheels = host.context("wheels");
  PluginContext& arm = host.context("arm");
  CHECK(rcand::sdk::find<PoseSource>(wheels) == nullptr);  // nothing offers it: null, never an error

  FakePose pose;
  REQUIRE(rcand::sdk::offer<PoseSource>(host, pose));
  REQUIRE(rcand::sdk::find<PoseSource>(wheels) == &pose);
  CHECK(rcand::sdk::find<PoseSource>(wheels)->read().pose.heading_deg == 45.0);
  FakePose another;
  CHECK_FALSE(rcand::sdk::offer<PoseSource>(arm, another));  // taken by the test's
  CHECK(logged(host, "instance 'arm': offer of service 'rcand.pose_source/1' refused: already offered"));

  FakeTrips trips;
  REQUIRE(rcand::sdk::offer<TripEstimator>(arm, trips));  // an instance's offer, found by the others and by the test
  CHECK(*rcand::sdk::find<TripEstimator>(wheels)->trip_seconds({}, 1, 1, 0.5) == 12.5);
  CHECK(rcand::sdk::find<TripEstimator>(host) == &trips);
  CHECK(host.service("rcand.trip_estimator/2") == nullptr);  // another version is another service

  // obstacles(), the deprecated shim, is the ObstacleSource service; set_obstacle_source() replaces it.
  FakeObstacles near;
  host.set_obstacle_source(&near);
  CHECK(wheels.obstacles() == &near);
  CHECK(rcand::sdk::find<ObstacleSource>(arm) == &near);
  host.set_obstacle_source(nullptr);
  CHECK(wheels.obstacles() == nullptr);
}

TEST_CASE("services: a failed instance's offers are not found; offers are withdrawn before shutdown()") {
  std::optional<bool> found_at_shutdown;
  {
    FakeHost host;
    auto& wheels = host.add_driver_instance<RecordingDrive>("wheels", host.clock());
    FakeTrips trips;
    REQUIRE(rcand::sdk::offer<TripEstimator>(host.context("wheels"), trips));
    CHECK(rcand::sdk::find<TripEstimator>(host) == &trips);
    wheels.fail_next();
    auto move = [](ActuatorDriver& d) { static_cast<DifferentialDrive&>(d).set_wheel_speeds(0.1, 0.1); };
    CHECK(host.motion().actuate("wheels", move) == GateStatus::ActuatorFailed);
    CHECK(rcand::sdk::find<TripEstimator>(host) == nullptr);

    auto& planner = host.add_driver_instance<OfferingDriver>("planner", found_at_shutdown);
    planner.ctx = &host.context("planner");
    CHECK_FALSE(rcand::sdk::offer<TripEstimator>(*planner.ctx, planner));  // the failed one still holds the id
  }
  {
    FakeHost host;
    auto& planner = host.add_driver_instance<OfferingDriver>("planner", found_at_shutdown);
    planner.ctx = &host.context("planner");
    REQUIRE(rcand::sdk::offer<TripEstimator>(*planner.ctx, planner));
    CHECK(rcand::sdk::find<TripEstimator>(host) == &planner);
    found_at_shutdown.reset();
  }
  REQUIRE(found_at_shutdown.has_value());
  CHECK_FALSE(*found_at_shutdown);  // the host withdrew it before calling shutdown()
}
