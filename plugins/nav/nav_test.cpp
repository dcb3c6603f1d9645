// nav on the fake host: the plan's arithmetic, validation that never moves a wheel, and whole jobs on the manual
// clock (the sleeper advances it), read back from a RecordingDrive's timeline at exact microseconds.
#include <doctest/doctest.h>

#include <rcand/sdk/testing/fake_host.hpp>
#include <rcand/sdk/testing/recording_drive.hpp>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <functional>
#include <limits>
#include <numbers>

#include "nav.hpp"

using nlohmann::json;
using rcand::plugins::nav::Nav;
using rcand::plugins::nav::Physics;
using rcand::plugins::nav::Plan;
using rcand::plugins::nav::plan_waypoint;
using rcand::sdk::Role;
using rcand::sdk::testing::FakeHost;
using rcand::sdk::testing::HostError;
using rcand::sdk::testing::RecordingDrive;

namespace {

// The kernel build registers Nav with its condition-variable sleeper (plugin.cpp); here the sleeper moves the
// fake host's manual clock, waking early exactly when the host latches the e-stop.
void register_nav_for_test(rcand::sdk::Registrar& registrar) {
  registrar.add_capability({"nav", true}, [](rcand::sdk::PluginContext& ctx) {
    return std::make_unique<Nav>(ctx, [&ctx](std::chrono::microseconds slice, const std::function<bool()>& woken) {
      if (!woken()) ctx.estop().sleep_unless_latched(slice);
    });
  });
}

}  // namespace

RCAND_PLUGIN("org.rcand.nav", "0.1.0", register_nav_for_test)

namespace {

json manifest() {
  std::ifstream in(RCAND_SOURCE_DIR "/manifests/nav.json");
  REQUIRE(in.good());
  return json::parse(in);
}

json robot(json extra = json::object()) {
  json config{{"physics", {{"wheel_circumference_m", 0.21}, {"turn_time_per_deg_s", 0.008}, {"max_wheel_rps", 1.0}}}};
  config.merge_patch(extra);
  return config;
}

// Reports `far_cm` until the manual clock reaches `near_at_us`, then `near_cm`.
struct ScriptedObstacles final : rcand::sdk::ObstacleSource {
  const rcand::sdk::Clock& clock;
  double far_cm, near_cm;
  std::int64_t near_at_us;
  mutable int reads = 0;
  mutable std::vector<std::int64_t> read_times;
  ScriptedObstacles(const rcand::sdk::Clock& c, double far, double near, std::int64_t at)
      : clock(c), far_cm(far), near_cm(near), near_at_us(at) {}
  rcand::sdk::ObstacleReading obstacles() const noexcept override {
    ++reads;
    read_times.push_back(clock.now_us());
    const double cm = clock.now_us() >= near_at_us ? near_cm : far_cm;
    return {true, cm, cm, cm, cm, 0};
  }
};

struct Fixture {
  FakeHost host;
  RecordingDrive& drive;
  explicit Fixture(json robot_config = robot(), json settings = json::object())
      : host(std::move(robot_config)), drive(host.add_driver_instance<RecordingDrive>("base", host.clock())) {
    host.load(RCAND_ENTRY_FUNCTION, manifest());
    host.add_capability("nav", std::move(settings));
  }
  rcand::sdk::Response waypoint(json body) { return host.call("POST", "/api/nav/waypoint", std::move(body), Role::User); }
  json status() { return host.call("GET", "/api/nav/status", nullptr, Role::Guest).body; }
};

json wp(double distance, double heading, double speed) {
  return {{"distance_m", distance}, {"heading_deg", heading}, {"speed", speed}};
}

}  // namespace

TEST_CASE("the plan: turn = |heading| x turn_time_per_deg_s / speed, drive = |distance| / (circumference x rps x speed)") {
  const Physics physics{0.21, 0.008, 1.0};
  auto plan = std::get<Plan>(plan_waypoint(wp(1.5, 90, 0.6), physics, 600'000'000));  // the seed's example
  CHECK(plan.turn_us == 1'200'000);
  CHECK(plan.drive_us == 11'904'762);
  CHECK(plan.eta_ms() == 13'105);
  CHECK(plan.turn_left() == -0.6);  // positive heading: counter-clockwise, left wheel backwards
  CHECK(plan.turn_right() == 0.6);
  CHECK(plan.drive_wheels() == 0.6);

  plan = std::get<Plan>(plan_waypoint({{"distance_m", -0.105}, {"heading_deg", -45}}, {0.21, 0.008, 2.0}, 600'000'000));
  CHECK(plan.waypoint.speed == 0.5);  // the seed's default
  CHECK(plan.turn_us == 720'000);
  CHECK(plan.drive_us == 500'000);   // max_wheel_rps doubles the ground speed
  CHECK(plan.turn_left() == 0.5);
  CHECK(plan.drive_wheels() == -0.5);

  CHECK(Physics::from(rcand::sdk::ConfigView(robot())).max_wheel_rps == 1.0);
  CHECK_THROWS_WITH_AS(Physics::from(rcand::sdk::ConfigView(json{{"physics", {{"wheel_circumference_m", 0.21}}}})),
                       doctest::Contains("physics.turn_time_per_deg_s"), rcand::sdk::ConfigError);
  CHECK_THROWS_WITH_AS(Physics::from(rcand::sdk::ConfigView(robot({{"physics", {{"max_wheel_rps", 0}}}}))),
                       doctest::Contains("physics.max_wheel_rps"), rcand::sdk::ConfigError);
}

TEST_CASE("each bad field answers 400 naming it, and no wheel moves") {
  Fixture f;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  const std::vector<std::pair<json, std::string>> cases = {
      {json::array({1, 2}), "body"},
      {json("go"), "body"},
      {{{"heading_deg", 0}}, "distance_m"},
      {{{"distance_m", nullptr}, {"heading_deg", 0}}, "distance_m"},
      {{{"distance_m", "1"}, {"heading_deg", 0}}, "distance_m"},
      {{{"distance_m", true}, {"heading_deg", 0}}, "distance_m"},
      {{{"distance_m", nan}, {"heading_deg", 0}}, "distance_m"},
      {{{"distance_m", inf}, {"heading_deg", 0}}, "distance_m"},
      {{{"distance_m", 1}}, "heading_deg"},
      {{{"distance_m", 1}, {"heading_deg", "left"}}, "heading_deg"},
      {{{"distance_m", 1}, {"heading_deg", -inf}}, "heading_deg"},
      {{{"distance_m", 1}, {"heading_deg", json::array({90})}}, "heading_deg"},
      {wp(1, 0, 0), "speed"},
      {wp(1, 0, -0.1), "speed"},
      {wp(1, 0, 1.01), "speed"},
      {wp(1, 0, nan), "speed"},
      {{{"distance_m", 1}, {"heading_deg", 0}, {"speed", "fast"}}, "speed"},
      {wp(1e12, 0, 1), "distance_m"},   // longer than max_job_ms
      {wp(0, 1e9, 1), "heading_deg"},
  };
  for (const auto& entry : cases) {
    // Named references, not structured bindings: CAPTURE makes a lambda, and clang 14 cannot capture a binding.
    const auto& body = std::get<0>(entry); const auto& field = std::get<1>(entry);
    CAPTURE(body.dump());
    const auto r = f.waypoint(body);
    CHECK(r.status == 400);
    CHECK(r.body["code"] == "BAD_REQUEST");
    CHECK(r.body["field"] == field);
    CHECK(r.body["error"].get<std::string>().find(field) != std::string::npos);
  }
  CHECK(f.drive.events().empty());
  CHECK(f.status()["state"] == "idle");
}

TEST_CASE("a waypoint turns, then drives, then stops, each for exactly the computed time") {
  Fixture f;
  const auto r = f.waypoint(wp(0.21, 90, 0.5));  // turn 1.44 s, drive 2 s
  REQUIRE(r.status == 200);
  CHECK(r.body["ok"] == true);
  CHECK(r.body["job_id"].get<std::string>().rfind("nav-", 0) == 0);
  CHECK(r.body["eta_ms"] == 3440);
  const auto events = f.drive.events();
  REQUIRE(events.size() == 3);
  CHECK(events[0].t_us == 0);
  CHECK(events[0].left == -0.5);
  CHECK(events[0].right == 0.5);
  CHECK(events[1].t_us == 1'440'000);
  CHECK(events[1].left == 0.5);
  CHECK(events[1].right == 0.5);
  CHECK(events[2].t_us == 3'440'000);
  CHECK(events[2].halt);

  const json status = f.status();
  CHECK(status["running"] == false);
  CHECK(status["state"] == "done");
  CHECK(status["job_id"] == r.body["job_id"]);
  CHECK(status["distance_m"] == 0.21);
  CHECK(status["heading_deg"] == 90.0);
  CHECK(status["speed"] == 0.5);
  CHECK(status["elapsed_ms"] == 3440);
  CHECK(status["eta_ms"] == 3440);
  CHECK(status["result"]["ok"] == true);
  CHECK(status["result"]["reason"] == "completed");
  CHECK(status["pose"]["x_m"].get<double>() == doctest::Approx(0.0));
  CHECK(status["pose"]["y_m"].get<double>() == doctest::Approx(0.21));
  CHECK(status["pose"]["heading_deg"].get<double>() == doctest::Approx(90.0));

  // A second job continues from that pose: a right turn back to 0 and a reverse drive.
  REQUIRE(f.waypoint(wp(-0.105, -90, 1.0)).status == 200);
  const json after = f.status();
  CHECK(after["pose"]["x_m"].get<double>() == doctest::Approx(-0.105));
  CHECK(after["pose"]["y_m"].get<double>() == doctest::Approx(0.21));
  CHECK(after["pose"]["heading_deg"].get<double>() == doctest::Approx(0.0));
}

TEST_CASE("the job publishes its status: at the start, at the turn, about 10 times a second while moving, at the end") {
  Fixture f;
  CHECK_FALSE(f.host.last_published_status("nav"));      // idle: nothing changed, the kernel asks status() instead
  REQUIRE(f.waypoint(wp(0.21, 90, 0.5)).status == 200);  // turn 1.44 s, drive 2 s, all inside the call
  const auto published = f.host.published_statuses("nav");
  REQUIRE(published.size() >= 3);
  CHECK(published.front()["running"] == true);
  CHECK(published.front()["state"] == "turning");
  CHECK(published.front()["elapsed_ms"] == 0);
  CHECK(published.back() == f.status());  // the last one is what status() says now: done, with the final pose
  CHECK(published.back()["state"] == "done");
  bool saw_driving = false;
  std::int64_t previous_ms = -1;
  for (std::size_t i = 1; i + 1 < published.size(); ++i) {
    const json& s = published[i];
    CHECK(s["running"] == true);
    saw_driving = saw_driving || s["state"] == "driving";
    CHECK(s["elapsed_ms"].get<std::int64_t>() > previous_ms);
    previous_ms = s["elapsed_ms"].get<std::int64_t>();
  }
  CHECK(saw_driving);
  // Rate-limited: 3.44 s of motion gives about 34 periodic publishes, plus the start, the turn and the end.
  CHECK(published.size() >= 30);
  CHECK(published.size() <= 40);
}

TEST_CASE("idle status: every field present, nulls where no job ran") {
  Fixture f;
  const json s = f.status();
  for (const char* key : {"running", "job_id", "state", "distance_m", "heading_deg", "speed", "elapsed_ms", "eta_ms", "result", "pose"})
    CHECK_MESSAGE(s.contains(key), key);
  CHECK(s["running"] == false);
  CHECK(s["state"] == "idle");
  CHECK(s["job_id"].is_null());
  CHECK(s["result"].is_null());
  CHECK(s["pose"] == json{{"x_m", 0.0}, {"y_m", 0.0}, {"heading_deg", 0.0}});
  // A zero waypoint is done at once and commands nothing.
  const auto r = f.waypoint(wp(0, 0, 0.5));
  CHECK(r.status == 200);
  CHECK(r.body["eta_ms"] == 0);
  CHECK(f.drive.events().empty());
  CHECK(f.status()["state"] == "done");
}

TEST_CASE("an e-stop mid-turn or mid-drive ends the job at that instant with the reason; nothing moves afterwards") {
  for (std::int64_t at : {700'000, 2'000'000}) {
    CAPTURE(at);
    Fixture f;
    f.host.latch_estop_at(at, "test");
    REQUIRE(f.waypoint(wp(0.21, 90, 0.5)).status == 200);
    const auto events = f.drive.events();
    REQUIRE(!events.empty());
    CHECK(events.back().halt);
    CHECK(events.back().t_us == at);
    for (const auto& e : events)
      if (!e.halt) CHECK(e.t_us < at);
    CHECK_FALSE(f.drive.moving());
    const json s = f.status();
    CHECK(s["running"] == false);
    CHECK(s["state"] == "aborted");
    CHECK(s["result"]["ok"] == false);
    CHECK(s["result"]["reason"] == "estop");
    CHECK(s["result"]["message"].get<std::string>().find(at < 1'440'000 ? "mid-turn" : "mid-drive") != std::string::npos);
    // The pose holds what actually ran: 700 ms of the turn, or the whole turn and 560 ms of the drive.
    if (at < 1'440'000) CHECK(s["pose"]["heading_deg"].get<double>() == doctest::Approx(43.75));
    else CHECK(s["pose"]["y_m"].get<double>() == doctest::Approx(0.0588));
    // Latched: a new job is refused before anything moves.
    const auto refused = f.waypoint(wp(1, 0, 0.5));
    CHECK(refused.status == 423);
    CHECK(refused.body["code"] == "ESTOP_ACTIVE");
    CHECK(f.drive.events().size() == events.size());
  }
}

TEST_CASE("a driver that throws ends the job with the motors at zero and a clear result") {
  SUBCASE("on the first command: 503, nothing runs") {
    Fixture f;
    f.drive.fail_next();
    const auto r = f.waypoint(wp(1, 90, 0.5));
    CHECK(r.status == 503);
    CHECK(r.body["code"] == "UNAVAILABLE");
    CHECK_FALSE(f.drive.moving());
    CHECK(f.status()["result"]["reason"] == "actuator_failed");
    CHECK(f.waypoint(wp(1, 0, 0.5)).status == 503);  // out of service from then on
  }
  SUBCASE("on the drive command, after the turn") {
    Fixture f;
    int commands = 0;
    f.drive.on_command([&] {
      if (++commands == 1) f.drive.fail_next();  // the turn goes through; the next command (the drive) throws
    });
    REQUIRE(f.waypoint(wp(0.21, 90, 0.5)).status == 200);
    CHECK_FALSE(f.drive.moving());
    CHECK(f.drive.events().back().halt);
    const json s = f.status();
    CHECK(s["state"] == "aborted");
    CHECK(s["result"]["reason"] == "actuator_failed");
    CHECK(f.host.task_failures().empty());  // the job caught it: the capability stays in service
  }
}

TEST_CASE("obstacles (§10.5): below the minimum before the job latches the e-stop and answers 423 without moving") {
  Fixture f(robot({{"agent", {{"min_obstacle_m", 0.3}}}}));
  ScriptedObstacles close(f.host.clock(), 20.0, 20.0, 0);
  f.host.set_obstacle_source(&close);
  const auto r = f.waypoint(wp(1, 0, 0.5));
  CHECK(r.status == 423);
  CHECK(r.body["code"] == "ESTOP_ACTIVE");
  CHECK(r.body["error"].get<std::string>().find("20.0 cm") != std::string::npos);
  CHECK(f.host.estopped());
  CHECK(f.drive.commands().empty());
}

TEST_CASE("obstacles (§10.5): checked at 40 Hz during the job; one appearing mid-drive latches within 25 ms") {
  SUBCASE("agent.min_obstacle_m") {
    Fixture f(robot({{"agent", {{"min_obstacle_m", 0.3}}}}));
    ScriptedObstacles source(f.host.clock(), 100.0, 25.0, 2'010'000);
    f.host.set_obstacle_source(&source);
    REQUIRE(f.waypoint(wp(0.21, 90, 0.5)).status == 200);
    CHECK(f.host.estopped());
    const auto events = f.drive.events();
    CHECK(events.back().halt);
    CHECK(events.back().t_us >= 2'010'000);
    CHECK(events.back().t_us <= 2'035'000);
    for (std::size_t i = 1; i < source.read_times.size(); ++i) CHECK(source.read_times[i] - source.read_times[i - 1] <= 25'000);
    const json s = f.status();
    CHECK(s["result"]["reason"] == "obstacle");
    CHECK(s["result"]["ok"] == false);
  }
  SUBCASE("safety.obstacle_stop_cm is an alias; an obstacle at the minimum exactly is not below it") {
    Fixture f(robot({{"safety", {{"obstacle_stop_cm", 25}}}}));
    ScriptedObstacles source(f.host.clock(), 25.0, 25.0, 0);
    f.host.set_obstacle_source(&source);
    REQUIRE(f.waypoint(wp(0.21, 0, 1.0)).status == 200);
    CHECK_FALSE(f.host.estopped());
    CHECK(f.status()["result"]["ok"] == true);
    CHECK(source.reads >= 40);  // before, and every 25 ms of the 1 s drive
  }
}

TEST_CASE("cancel without a job is a harmless no-op; cancel is never refused by the e-stop") {
  Fixture f;
  auto r = f.host.call("POST", "/api/nav/cancel", nullptr, Role::User);
  CHECK(r.status == 200);
  CHECK(r.body["cancelled"] == false);
  f.host.latch_estop("test");
  CHECK(f.host.call("POST", "/api/nav/cancel", nullptr, Role::User).status == 200);
  CHECK(f.host.call("POST", "/api/nav/cancel", nullptr, Role::Guest).status == 403);
  CHECK(f.host.call("POST", "/api/nav/waypoint", wp(1, 0, 0.5), Role::Guest).status == 403);
}

TEST_CASE("no physics: the capability refuses to start, naming the key") {
  FakeHost host(json{{"physics", {{"turn_time_per_deg_s", 0.008}}}});
  host.add_driver_instance<RecordingDrive>("base", host.clock());
  host.load(RCAND_ENTRY_FUNCTION, manifest());
  CHECK_THROWS_WITH_AS(host.add_capability("nav"), doctest::Contains("physics.wheel_circumference_m"), HostError);
}

// ---- the services nav offers (rcand/sdk/services.hpp) ------------------------------------------------------------

namespace {

// An obstacle source that, each time the job checks it (every 50 ms), records what nav's PoseSource says then.
struct PoseProbe final : rcand::sdk::ObstacleSource {
  const FakeHost& host;
  mutable std::vector<rcand::sdk::PoseReading> seen;
  explicit PoseProbe(const FakeHost& h) : host(h) {}
  rcand::sdk::ObstacleReading obstacles() const noexcept override {
    if (const auto* pose = rcand::sdk::find<rcand::sdk::PoseSource>(host)) seen.push_back(pose->read());
    return {true, 500, 500, 500, 500, 0};
  }
};

}  // namespace

TEST_CASE("nav offers its PoseSource: the live pose, busy while a job runs, equal to its status") {
  Fixture f(robot({{"safety", {{"obstacle_stop_cm", 5}}}}));
  const auto* pose = rcand::sdk::find<rcand::sdk::PoseSource>(f.host);
  REQUIRE(pose != nullptr);
  CHECK(pose == &f.host.capability<Nav>("nav"));  // nav itself, as its PoseSource base
  auto idle = pose->read();
  CHECK(idle.available);
  CHECK_FALSE(idle.busy);
  CHECK(idle.pose.x_m == 0.0);

  PoseProbe probe(f.host);
  f.host.set_obstacle_source(&probe);
  REQUIRE(f.waypoint(wp(0.21, 90, 0.5)).status == 200);  // turn 1.44 s, drive 2 s, all inside the call
  REQUIRE(probe.seen.size() >= 60);
  CHECK_FALSE(probe.seen.front().busy);  // the handler's check, before the job starts
  double heading = -1.0;
  for (std::size_t i = 1; i < probe.seen.size(); ++i) {
    const auto& reading = probe.seen[i];
    CHECK(reading.busy);
    CHECK(reading.pose.heading_deg >= heading);  // turning left towards 90, then driving: never back
    heading = reading.pose.heading_deg;
  }
  CHECK(probe.seen[probe.seen.size() / 4].pose.heading_deg > 0.0);  // mid-turn: moving, not the committed pose

  const auto done = pose->read();
  CHECK_FALSE(done.busy);
  const json status = f.status();
  CHECK(done.pose.x_m == status["pose"]["x_m"].get<double>());
  CHECK(done.pose.y_m == status["pose"]["y_m"].get<double>());
  CHECK(done.pose.heading_deg == status["pose"]["heading_deg"].get<double>());
}

TEST_CASE("nav offers its TripEstimator: a trip costs what the equivalent waypoint would take") {
  Fixture f;
  const auto* trips = rcand::sdk::find<rcand::sdk::TripEstimator>(f.host);
  REQUIRE(trips != nullptr);
  const Physics physics{0.21, 0.008, 1.0};  // robot()'s
  auto waypoint_s = [&](double distance, double heading, double speed) {
    const auto plan = std::get<Plan>(plan_waypoint(wp(distance, heading, speed), physics, 600'000'000));
    return static_cast<double>(plan.turn_us + plan.drive_us) / 1e6;
  };
  // (0,0) facing 0 -> (3,4): turn 53.13 deg left, drive 5 m.
  CHECK(*trips->trip_seconds({0, 0, 0}, 3, 4, 0.5) == doctest::Approx(waypoint_s(5, 53.130102354, 0.5)).epsilon(1e-6));
  // Already facing it: drive only. The shorter way round: from 170 deg to a point at -170 deg is a 20 deg turn.
  CHECK(*trips->trip_seconds({1, 1, 90}, 1, 3, 1.0) == doctest::Approx(waypoint_s(2, 0, 1.0)).epsilon(1e-6));
  const double at = -170.0 * std::numbers::pi / 180.0;
  CHECK(*trips->trip_seconds({0, 0, 170}, std::cos(at), std::sin(at), 0.5) ==
        doctest::Approx(waypoint_s(1, 20, 0.5)).epsilon(1e-6));
  CHECK(*trips->trip_seconds({2, 2, 45}, 2, 2, 0.5) == 0.0);  // already there
  // No job-length limit (a waypoint that long would be refused), and a speed a waypoint would refuse gives nothing.
  CHECK(*trips->trip_seconds({0, 0, 0}, 1e6, 0, 0.5) > 600'000.0);
  CHECK_FALSE(trips->trip_seconds({0, 0, 0}, 1, 0, 0.0));
  CHECK_FALSE(trips->trip_seconds({0, 0, 0}, 1, 0, 1.5));
  CHECK_FALSE(trips->trip_seconds({0, 0, 0}, std::numeric_limits<double>::infinity(), 0, 0.5));
}

// ---- depth that cannot be read (issue 15): unavailable is not free space --------------------------------------

namespace {

using rcand::sdk::ObstacleReading;

// Answers what `script` says at the manual clock's time.
struct ObstacleScript final : rcand::sdk::ObstacleSource {
  const rcand::sdk::Clock& clock;
  std::function<ObstacleReading(std::int64_t now_us)> script;
  mutable std::vector<std::int64_t> read_times;
  ObstacleScript(const rcand::sdk::Clock& c, std::function<ObstacleReading(std::int64_t)> s) : clock(c), script(std::move(s)) {}
  ObstacleReading obstacles() const noexcept override {
    read_times.push_back(clock.now_us());
    return script(clock.now_us());
  }
};

ObstacleReading reading(double left, double center, double right, std::int64_t timestamp_ms) {
  return {true, left, center, right, std::min({left, center, right}), timestamp_ms};
}

// The e-stop reason the fake host logged ("e-stop latched: <reason>"), or empty.
std::string estop_reason(const FakeHost& host) {
  for (const auto& line : host.log_lines())
    if (const auto at = line.find("e-stop latched: "); at != std::string::npos) return line.substr(at + 16);
  return {};
}

}  // namespace

TEST_CASE("depth unavailable before the job: 503 depth_unavailable, nothing latched, not a wheel moves") {
  SUBCASE("no fresh reading") {
    Fixture f(robot({{"agent", {{"min_obstacle_m", 0.3}}}}));
    ObstacleScript none(f.host.clock(), [](std::int64_t) { return ObstacleReading{}; });
    f.host.set_obstacle_source(&none);
    const auto r = f.waypoint(wp(1, 0, 0.5));
    CHECK(r.status == 503);
    CHECK(r.body["code"] == "UNAVAILABLE");
    CHECK(r.body["reason"] == "depth_unavailable");
    CHECK(r.body["error"].get<std::string>().find("depth unavailable (no depth reading)") != std::string::npos);
  }
  SUBCASE("camera.depth declared but no plugin offers the zones") {
    Fixture f(robot({{"safety", {{"obstacle_stop_cm", 30}}}, {"camera", {{"type", "synthetic"}, {"depth", "synthetic"}}}}));
    const auto r = f.waypoint(wp(1, 0, 0.5));
    CHECK(r.status == 503);
    CHECK(r.body["error"].get<std::string>().find("no plugin offers the zones") != std::string::npos);
  }
  SUBCASE("a non-finite zone") {
    Fixture f(robot({{"agent", {{"min_obstacle_m", 0.3}}}}));
    ObstacleScript nan(f.host.clock(),
                       [](std::int64_t) { return reading(100, std::numeric_limits<double>::quiet_NaN(), 100, 1); });
    f.host.set_obstacle_source(&nan);
    CHECK(f.waypoint(wp(1, 0, 0.5)).status == 503);
  }
  Fixture f(robot({{"agent", {{"min_obstacle_m", 0.3}}}}));
  ObstacleScript none(f.host.clock(), [](std::int64_t) { return ObstacleReading{}; });
  f.host.set_obstacle_source(&none);
  REQUIRE(f.waypoint(wp(1, 0, 0.5)).status == 503);
  CHECK_FALSE(f.host.estopped());
  CHECK(f.drive.commands().empty());
  CHECK(f.status()["running"] == false);
}

TEST_CASE("depth going stale mid-drive latches within 25 ms; the reason names it and carries the last frame's time") {
  Fixture f(robot({{"agent", {{"min_obstacle_m", 0.3}}}}));
  // Fresh frames (dated now) until 1.5 s; from then on the source reports unavailable, still dating the frame it
  // last had (as vision's DepthFeed does).
  constexpr std::int64_t wall0 = rcand::sdk::testing::ManualClock::kWallEpochMs;  // a constant: no capture needed
  ObstacleScript stale(f.host.clock(), [](std::int64_t now) {
    if (now < 1'500'000) return reading(200, 150, 300, wall0 + now / 1000);
    ObstacleReading r = reading(200, 150, 300, wall0 + 1'480);
    r.available = false;
    return r;
  });
  f.host.set_obstacle_source(&stale);
  REQUIRE(f.waypoint(wp(0.21, 0, 0.5)).status == 200);  // a 2 s drive
  CHECK(f.host.estopped());
  const auto events = f.drive.events();
  CHECK(events.back().halt);
  CHECK(events.back().t_us >= 1'500'000);
  CHECK(events.back().t_us <= 1'525'000);
  for (std::size_t i = 1; i < stale.read_times.size(); ++i) CHECK(stale.read_times[i] - stale.read_times[i - 1] <= 25'000);
  const json s = f.status();
  CHECK(s["result"]["reason"] == "depth_unavailable");
  CHECK(s["result"]["message"].get<std::string>().find("depth unavailable (stale: the last depth frame is") != std::string::npos);
  const std::string reason = estop_reason(f.host);
  CHECK(reason.rfind("nav: depth unavailable (stale: the last depth frame is ", 0) == 0);
  CHECK(reason.find(" ms old) while moving [depth available=false timestamp_ms=" + std::to_string(wall0 + 1'480) +
                    " min_cm=30.0]") != std::string::npos);
}

TEST_CASE("depth vanishing mid-turn (the source withdrawn while camera.depth is declared) latches too") {
  Fixture f(robot({{"agent", {{"min_obstacle_m", 0.3}}}, {"camera", {{"depth", "synthetic"}}}}));
  ScriptedObstacles far(f.host.clock(), 300.0, 300.0, 0);
  f.host.set_obstacle_source(&far);
  f.drive.on_command([&] { f.host.set_obstacle_source(nullptr); });  // gone as soon as the turn starts
  REQUIRE(f.waypoint(wp(0.21, 90, 0.5)).status == 200);
  CHECK(f.host.estopped());
  CHECK(f.drive.events().back().t_us <= 25'000);
  CHECK(f.status()["result"]["reason"] == "depth_unavailable");
  CHECK(estop_reason(f.host).find("no plugin offers the zones) while moving") != std::string::npos);
}

TEST_CASE("the obstacle stop's e-stop reason carries the zones and the frame time in the fixed form") {
  Fixture f(robot({{"safety", {{"obstacle_stop_cm", 30}}}}));
  ObstacleScript source(f.host.clock(), [](std::int64_t now) {
    return now < 1'000'000 ? reading(120, 250, 400, 1'700'000'000'100) : reading(45.5, 22.25, 400, 1'700'000'001'000);
  });
  f.host.set_obstacle_source(&source);
  REQUIRE(f.waypoint(wp(0.21, 0, 0.5)).status == 200);
  CHECK(f.host.estopped());
  CHECK(f.status()["result"]["reason"] == "obstacle");
  CHECK(estop_reason(f.host) ==
        "nav: obstacle at 22.2 cm, below the minimum 30.0 cm while moving [depth available=true left_cm=45.5 "
        "center_cm=22.2 right_cm=400.0 nearest_cm=22.2 timestamp_ms=1700000001000 min_cm=30.0]");
}

TEST_CASE("without a minimum, or with no source and no depth declared, unreadable depth stops nothing") {
  SUBCASE("no minimum") {
    Fixture f;
    ObstacleScript none(f.host.clock(), [](std::int64_t) { return ObstacleReading{}; });
    f.host.set_obstacle_source(&none);
    REQUIRE(f.waypoint(wp(0.21, 0, 1.0)).status == 200);
    CHECK(f.status()["result"]["ok"] == true);
    CHECK(none.read_times.empty());  // nothing to compare against: not even read
  }
  SUBCASE("a minimum, but no depth at all") {
    Fixture f(robot({{"agent", {{"min_obstacle_m", 0.3}}}}));
    REQUIRE(f.waypoint(wp(0.21, 0, 1.0)).status == 200);
    CHECK(f.status()["result"]["ok"] == true);
    CHECK_FALSE(f.host.estopped());
  }
}

TEST_CASE("obstacle::judge: each verdict") {
  using rcand::plugins::obstacle::judge;
  using Kind = rcand::plugins::obstacle::Verdict::Kind;
  struct Fixed final : rcand::sdk::ObstacleSource {
    ObstacleReading r;
    ObstacleReading obstacles() const noexcept override { return r; }
  };
  Fixed s;
  s.r = reading(40, 30, 50, 1000);
  CHECK(judge(&s, false, 30.0, 2000).kind == Kind::Clear);  // at the minimum exactly is not below it
  CHECK(judge(&s, false, std::nullopt, 2000).kind == Kind::Clear);
  CHECK(judge(&s, false, 30.5, 2000).kind == Kind::Obstacle);
  s.r.right_cm = std::numeric_limits<double>::infinity();
  CHECK(judge(&s, false, 10.0, 2000).kind == Kind::Unavailable);
  s.r.available = false;
  const auto stale = judge(&s, false, 10.0, 1250);
  CHECK(stale.kind == Kind::Unavailable);
  CHECK(stale.why == "depth unavailable (stale: the last depth frame is 250 ms old)");
  CHECK(stale.record == "[depth available=false timestamp_ms=1000 min_cm=10.0]");
  CHECK(judge(nullptr, false, 10.0, 0).kind == Kind::Clear);
  CHECK(judge(nullptr, true, 10.0, 0).kind == Kind::Unavailable);
  CHECK(judge(nullptr, true, std::nullopt, 0).kind == Kind::Clear);
}
