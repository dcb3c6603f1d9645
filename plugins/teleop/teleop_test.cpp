// teleop on the fake host, with a RecordingDrive as the differential drive behind the gate.
#include <doctest/doctest.h>

#include <rcand/sdk/testing/fake_host.hpp>
#include <rcand/sdk/testing/recording_drive.hpp>

#include <chrono>
#include <fstream>
#include <functional>
#include <limits>

#include "teleop.hpp"

extern "C" const rcand_plugin_descriptor* RCAND_ENTRY_FUNCTION(void);

using namespace std::chrono_literals;
using nlohmann::json;
using rcand::sdk::Role;
using rcand::sdk::testing::FakeHost;
using rcand::sdk::testing::HostError;
using rcand::sdk::testing::RecordingDrive;

namespace {

json manifest() {
  std::ifstream in(RCAND_SOURCE_DIR "/manifests/teleop.json");
  REQUIRE(in.good());
  return json::parse(in);
}

json move(double linear, double angular) { return {{"type", "move"}, {"linear", linear}, {"angular", angular}}; }
json move_for(double linear, double angular, int duration_ms) {
  auto body = move(linear, angular);
  body["duration_ms"] = duration_ms;
  return body;
}

struct Fixture {
  FakeHost host;
  RecordingDrive& drive;
  explicit Fixture(json robot_config = json::object(), json settings = json::object())
      : host(std::move(robot_config)), drive(host.add_driver_instance<RecordingDrive>("base", host.clock())) {
    host.load(RCAND_ENTRY_FUNCTION, manifest());
    host.add_capability("teleop", std::move(settings));
  }
  rcand::sdk::Response post(json body, Role role = Role::User) { return host.call("POST", "/api/action", std::move(body), role); }
  std::size_t halts() const {
    std::size_t n = 0;
    for (const auto& e : drive.events()) n += e.halt;
    return n;
  }
};

}  // namespace

TEST_CASE("mix: left = linear - angular, right = linear + angular, scaled so neither exceeds 1") {
  using rcand::plugins::teleop::mix;
  CHECK(mix(0.5, 0.25).left == doctest::Approx(0.25));
  CHECK(mix(0.5, 0.25).right == doctest::Approx(0.75));
  CHECK(mix(1.0, 1.0).left == doctest::Approx(0.0));
  CHECK(mix(1.0, 1.0).right == doctest::Approx(1.0));
  CHECK(mix(1.0, -0.5).left == doctest::Approx(1.0));
  CHECK(mix(1.0, -0.5).right == doctest::Approx(1.0 / 3.0));
  CHECK(mix(0.0, -1.0).left == doctest::Approx(1.0));
  CHECK(mix(0.0, -1.0).right == doctest::Approx(-1.0));
}

TEST_CASE("move mixes, drives the wheels and answers every field") {
  Fixture f;
  auto r = f.post(move(0.5, 0.25));
  REQUIRE(r.status == 200);
  CHECK(r.body["ok"] == true);
  CHECK(r.body["type"] == "move");
  CHECK(r.body["linear"] == 0.5);
  CHECK(r.body["angular"] == 0.25);
  CHECK(r.body["left"].get<double>() == doctest::Approx(0.25));
  CHECK(r.body["right"].get<double>() == doctest::Approx(0.75));
  CHECK(r.body["duration_ms"].is_null());
  CHECK(r.body["deadman_ms"] == 500);
  CHECK(f.drive.left() == doctest::Approx(0.25));
  CHECK(f.drive.right() == doctest::Approx(0.75));

  r = f.post(move(1.0, -1.0));  // the full range is accepted, then mixed: left 2, right 0 -> scaled to 1, 0
  CHECK(r.status == 200);
  CHECK(r.body["linear"] == 1.0);
  CHECK(r.body["angular"] == -1.0);
  CHECK(f.drive.left() == doctest::Approx(1.0));
  CHECK(f.drive.right() == doctest::Approx(0.0));
}

TEST_CASE("out of range is refused with 400 naming the field, never clamped to full speed") {
  Fixture f;
  for (const double linear : {5.0, -1.0001, 1e300, -1e300}) {
    CAPTURE(linear);
    const auto r = f.post(move(linear, 0.0));
    CHECK(r.status == 400);
    CHECK(r.body["field"] == "linear");
    CHECK(r.body["error"].get<std::string>().find("[-1, 1]") != std::string::npos);
  }
  for (const double angular : {2.0, -1e300}) {
    CAPTURE(angular);
    const auto r = f.post(move(0.5, angular));
    CHECK(r.status == 400);
    CHECK(r.body["field"] == "angular");
  }
  CHECK(f.drive.events().empty());
}

TEST_CASE("linear beyond safety.max_linear_speed is refused, naming the limit and where it comes from") {
  Fixture f({{"safety", {{"max_linear_speed", 0.4}}}});
  auto r = f.post(move(0.4, 0.0));
  CHECK(r.status == 200);
  CHECK(f.drive.left() == doctest::Approx(0.4));
  r = f.post(move(-0.9, 0.0));
  CHECK(r.status == 400);
  CHECK(r.body["field"] == "linear");
  const std::string message = r.body["error"];
  CHECK(message.find("[-0.4, 0.4]") != std::string::npos);
  CHECK(message.find("safety.max_linear_speed") != std::string::npos);
  CHECK(f.drive.left() == doctest::Approx(0.4));  // the refused move reached nothing
}

TEST_CASE("each bad field answers 400 naming it, and the driver receives nothing") {
  Fixture f;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  const std::vector<std::pair<json, std::string>> cases = {
      {{{"type", "move"}}, "linear"},
      {{{"type", "move"}, {"linear", nullptr}, {"angular", 0.0}}, "linear"},
      {{{"type", "move"}, {"linear", "fast"}, {"angular", 0.0}}, "linear"},
      {{{"type", "move"}, {"linear", true}, {"angular", 0.0}}, "linear"},
      {{{"type", "move"}, {"linear", nan}, {"angular", 0.0}}, "linear"},
      {{{"type", "move"}, {"linear", inf}, {"angular", 0.0}}, "linear"},
      {{{"type", "move"}, {"linear", 0.5}, {"angular", nullptr}}, "angular"},
      {{{"type", "move"}, {"linear", 0.5}, {"angular", "left"}}, "angular"},
      {{{"type", "move"}, {"linear", 0.5}, {"angular", -inf}}, "angular"},
      {{{"type", "move"}, {"linear", 0.5}, {"angular", json::array({1})}}, "angular"},
      {move_for(0.5, 0.0, 0), "duration_ms"},
      {move_for(0.5, 0.0, 60001), "duration_ms"},
      {move_for(0.5, 0.0, -5), "duration_ms"},
      {{{"type", "move"}, {"linear", 0.5}, {"angular", 0.0}, {"duration_ms", 1.5}}, "duration_ms"},
      {{{"type", "move"}, {"linear", 0.5}, {"angular", 0.0}, {"duration_ms", "100"}}, "duration_ms"},
      {{{"type", "move"}, {"linear", 0.5}, {"angular", 0.0}, {"duration_ms", 18446744073709551615ULL}}, "duration_ms"},
  };
  for (const auto& entry : cases) {
    // Named references, not structured bindings: CAPTURE makes a lambda, and clang 14 cannot capture a binding.
    const auto& body = std::get<0>(entry); const auto& field = std::get<1>(entry);
    CAPTURE(body.dump());
    const auto r = f.post(body);
    CHECK(r.status == 400);
    CHECK(r.body["code"] == "BAD_REQUEST");
    CHECK(r.body["field"] == field);
    CHECK(r.body["error"].get<std::string>().find(field) != std::string::npos);
  }
  CHECK(f.drive.events().empty());
  CHECK(f.host.pending_tasks() == 0);
}

TEST_CASE("a move names linear, angular or both: the one left out is 0") {
  Fixture f;
  auto r = f.post({{"type", "move"}, {"linear", 0.5}});
  CHECK(r.status == 200);
  CHECK(r.body["angular"] == 0.0);
  CHECK(f.drive.left() == doctest::Approx(0.5));
  CHECK(f.drive.right() == doctest::Approx(0.5));
  r = f.post({{"type", "move"}, {"angular", 0.25}});
  CHECK(r.status == 200);
  CHECK(r.body["linear"] == 0.0);
  CHECK(f.drive.left() == doctest::Approx(-0.25));
  CHECK(f.drive.right() == doctest::Approx(0.25));
}

TEST_CASE("duration_ms stops the motion at exactly that time") {
  Fixture f;
  const auto r = f.post(move_for(0.5, 0.0, 300));
  CHECK(r.body["duration_ms"] == 300);
  CHECK(r.body["deadman_ms"].is_null());
  f.host.advance(299ms);
  CHECK(f.drive.moving());
  f.host.advance(1ms);
  CHECK_FALSE(f.drive.moving());
  REQUIRE(f.drive.events().size() == 2);
  CHECK(f.drive.events()[1].halt);
  CHECK(f.drive.events()[1].t_us == 300'000);
  // A duration longer than the watchdog is not cut short by the dead-man.
  f.post(move_for(0.5, 0.0, 2000));
  f.host.advance(1999ms);
  CHECK(f.drive.moving());
  f.host.advance(1ms);
  CHECK_FALSE(f.drive.moving());
}

TEST_CASE("dead-man: a move without duration_ms stops at watchdog_ms") {
  SUBCASE("safety.watchdog_ms from the robot config") {
    Fixture f({{"safety", {{"watchdog_ms", 200}}}});
    CHECK(f.post(move(0.5, 0.0)).body["deadman_ms"] == 200);
    f.host.advance(199ms);
    CHECK(f.drive.moving());
    f.host.advance(1ms);
    CHECK_FALSE(f.drive.moving());
    CHECK(f.drive.events().back().t_us == 200'000);
  }
  SUBCASE("the capability's own watchdog_ms wins") {
    Fixture f({{"safety", {{"watchdog_ms", 200}}}}, {{"watchdog_ms", 80}});
    f.post(move(0.5, 0.0));
    f.host.advance(80ms);
    CHECK_FALSE(f.drive.moving());
    CHECK(f.drive.events().back().t_us == 80'000);
  }
  SUBCASE("default 500") {
    Fixture f;
    f.post(move(0.5, 0.0));
    f.host.advance(499ms);
    CHECK(f.drive.moving());
    f.host.advance(1ms);
    CHECK_FALSE(f.drive.moving());
  }
}

TEST_CASE("a refreshed dead-man keeps moving; it stops watchdog_ms after the last refresh") {
  Fixture f({{"safety", {{"watchdog_ms", 200}}}});
  for (int i = 0; i < 10; ++i) {
    REQUIRE(f.post(move(0.5, 0.0)).status == 200);
    f.host.advance(150ms);
    CHECK(f.drive.moving());
  }
  CHECK(f.halts() == 0);
  f.host.advance(49ms);
  CHECK(f.drive.moving());
  f.host.advance(1ms);
  CHECK_FALSE(f.drive.moving());
  CHECK(f.drive.events().back().t_us == 9 * 150'000 + 200'000);
}

TEST_CASE("an old timer never stops a newer command, even when its cancel lost the race") {
  Fixture f;
  f.host.simulate_cancel_race(true);  // cancel() fails: the old timer still runs, and must do nothing
  f.post(move_for(0.5, 0.0, 100));
  f.host.advance(50ms);
  f.post(move_for(0.8, 0.0, 500));
  f.host.advance(50ms);  // t = 100 ms: the first move's timer fires
  CHECK(f.drive.moving());
  CHECK(f.halts() == 0);
  CHECK(f.host.pending_tasks() == 1);
  f.host.advance(449ms);
  CHECK(f.drive.moving());
  f.host.advance(1ms);  // t = 550 ms
  CHECK_FALSE(f.drive.moving());
  CHECK(f.halts() == 1);
  CHECK(f.drive.events().back().t_us == 550'000);
}

TEST_CASE("stop halts at once, cancels the timer, and is never refused by the e-stop") {
  Fixture f;
  f.post(move(0.5, 0.0));
  f.host.advance(10ms);
  const auto r = f.post({{"type", "stop"}});
  CHECK(r.status == 200);
  CHECK(r.body == json{{"ok", true}, {"type", "stop"}});
  CHECK_FALSE(f.drive.moving());
  CHECK(f.halts() == 1);
  CHECK(f.host.pending_tasks() == 0);
  f.host.advance(1s);
  CHECK(f.halts() == 1);
  CHECK(f.host.call("GET", "/api/status").status == 404);  // teleop serves no other route

  f.host.latch_estop("test");
  CHECK(f.post({{"type", "stop"}}).status == 200);
  CHECK(f.post({{"type", "stop"}}, Role::Guest).status == 403);
}

TEST_CASE("e-stop: move answers 423 and the driver receives nothing; on_estop cancels the dead-man") {
  Fixture f;
  f.host.latch_estop("test");
  const auto r = f.post(move(0.5, 0.0));
  CHECK(r.status == 423);
  CHECK(r.body["code"] == "ESTOP_ACTIVE");
  CHECK(f.drive.commands().empty());

  f.host.clear_estop();
  REQUIRE(f.post(move(0.5, 0.0)).status == 200);
  CHECK(f.host.pending_tasks() == 1);
  f.host.latch_estop("again");  // the host halts the drive, then on_estop cancels the timer
  CHECK_FALSE(f.drive.moving());
  CHECK(f.host.pending_tasks() == 0);
  CHECK(f.host.capability<rcand::plugins::teleop::Teleop>("teleop").status()["moving"] == false);
}

TEST_CASE("an e-stop latching while the move command runs: 423, wheels halted, no timer left") {
  Fixture f;
  f.drive.on_command([&] { f.host.latch_estop("racing"); });
  const auto r = f.post(move(0.5, 0.0));
  CHECK(r.status == 423);
  CHECK_FALSE(f.drive.moving());
  CHECK(f.drive.events().back().halt);
  CHECK(f.host.pending_tasks() == 0);
}

TEST_CASE("no differential drive: 503 UNAVAILABLE") {
  FakeHost host;
  host.load(RCAND_ENTRY_FUNCTION, manifest());
  host.add_capability("teleop");
  for (const char* type : {"move", "stop"}) {
    const auto r = host.call("POST", "/api/action", {{"type", type}, {"linear", 0.1}, {"angular", 0.0}});
    CHECK(r.status == 503);
    CHECK(r.body["code"] == "UNAVAILABLE");
  }
  CHECK(host.capability<rcand::plugins::teleop::Teleop>("teleop").status()["driver"].is_null());
}

TEST_CASE("the driver setting picks the actuator; an unknown one answers 503") {
  FakeHost host;
  auto& first = host.add_driver_instance<RecordingDrive>("left_base", host.clock());
  auto& second = host.add_driver_instance<RecordingDrive>("right_base", host.clock());
  host.load(RCAND_ENTRY_FUNCTION, manifest());
  host.add_capability("teleop", {{"driver", "right_base"}});
  CHECK(host.call("POST", "/api/action", move(0.5, 0.0)).status == 200);
  CHECK(first.events().empty());
  CHECK(second.moving());
  const auto status = host.capability<rcand::plugins::teleop::Teleop>("teleop").status();
  CHECK(status["driver"] == "right_base");
  CHECK(status["moving"] == true);
  CHECK(status["last_command_us"] == 0);

  FakeHost other;
  other.add_driver_instance<RecordingDrive>("base", other.clock());
  other.load(RCAND_ENTRY_FUNCTION, manifest());
  other.add_capability("teleop", {{"driver", "nope"}});
  CHECK(other.call("POST", "/api/action", move(0.5, 0.0)).status == 503);
}

TEST_CASE("a bad watchdog_ms is refused naming the key") {
  FakeHost host({{"safety", {{"watchdog_ms", 0}}}});
  host.load(RCAND_ENTRY_FUNCTION, manifest());
  CHECK_THROWS_WITH_AS(host.add_capability("teleop"), doctest::Contains("safety.watchdog_ms"), HostError);
  FakeHost schema_host;
  schema_host.load(RCAND_ENTRY_FUNCTION, manifest());
  CHECK_THROWS_WITH_AS(schema_host.add_capability("teleop", {{"watchdog_ms", "soon"}}), doctest::Contains("watchdog_ms"),
                       HostError);
}

TEST_CASE("teleop publishes its status after every change: move, the dead-man's stop, stop, the e-stop") {
  Fixture f;
  auto& teleop = f.host.capability<rcand::plugins::teleop::Teleop>("teleop");
  auto moving = [&] { return f.host.last_published_status("teleop").value_or(json())["moving"]; };
  CHECK_FALSE(f.host.last_published_status("teleop"));

  REQUIRE(f.post(move_for(0.5, 0.0, 100)).status == 200);
  CHECK(moving() == true);
  CHECK(*f.host.last_published_status("teleop") == teleop.status());
  f.host.advance(100ms);  // the duration ends: the timer halts and publishes
  CHECK(moving() == false);
  CHECK(*f.host.last_published_status("teleop") == teleop.status());

  REQUIRE(f.post(move(0.5, 0.0)).status == 200);
  CHECK(moving() == true);
  REQUIRE(f.post({{"type", "stop"}}).status == 200);
  CHECK(moving() == false);

  REQUIRE(f.post(move(0.5, 0.0)).status == 200);
  const auto before = f.host.published_statuses("teleop").size();
  f.host.latch_estop("test");
  CHECK(f.host.published_statuses("teleop").size() == before + 1);
  CHECK(moving() == false);
}

// ---- depth obstacles (issue 15; the rule: plugins/nav/obstacle_guard.hpp) ----------------------------------------

namespace {

using rcand::sdk::ObstacleReading;

// Answers what `script` says at the manual clock's time, and records when it was read.
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

ObstacleReading at_cm(double cm) { return {true, cm, cm, cm, cm, 1'700'000'000'000}; }
// `far_cm` before `near_at_us` on the manual clock, `near_cm` from then on.
std::function<ObstacleReading(std::int64_t)> appearing(double far_cm, double near_cm, std::int64_t near_at_us) {
  return [=](std::int64_t now) { return at_cm(now >= near_at_us ? near_cm : far_cm); };
}

json min_30cm() { return {{"agent", {{"min_obstacle_m", 0.3}}}}; }

std::string estop_reason(const FakeHost& host) {
  for (const auto& line : host.log_lines())
    if (const auto at = line.find("e-stop latched: "); at != std::string::npos) return line.substr(at + 16);
  return {};
}

}  // namespace

TEST_CASE("teleop: forward towards an obstacle below the minimum is 423 and latches; reversing and turning are not checked") {
  for (const json& config : {min_30cm(), json{{"safety", {{"obstacle_stop_cm", 30}}}}}) {
    CAPTURE(config.dump());
    Fixture f(config);
    ObstacleScript near(f.host.clock(), appearing(20, 20, 0));
    f.host.set_obstacle_source(&near);
    const auto r = f.post(move(0.3, 0.2));
    CHECK(r.status == 423);
    CHECK(r.body["code"] == "ESTOP_ACTIVE");
    CHECK(r.body["reason"] == "obstacle");
    CHECK(r.body["error"].get<std::string>().find("obstacle at 20.0 cm, below the minimum 30.0 cm") != std::string::npos);
    CHECK(f.host.estopped());
    CHECK(f.drive.commands().empty());
    CHECK(estop_reason(f.host) ==
          "teleop: obstacle at 20.0 cm, below the minimum 30.0 cm [depth available=true left_cm=20.0 center_cm=20.0 "
          "right_cm=20.0 nearest_cm=20.0 timestamp_ms=1700000000000 min_cm=30.0]");

    // Released by an owner with the obstacle still there: the way out is backwards or round, and those run unwatched.
    f.host.clear_estop();
    const std::size_t reads = near.read_times.size();
    CHECK(f.post(move_for(-0.3, 0.0, 200)).status == 200);
    CHECK(f.post(move_for(0.0, 0.5, 200)).status == 200);
    f.host.advance(300ms);
    CHECK_FALSE(f.host.estopped());
    CHECK(near.read_times.size() == reads);
    CHECK(f.drive.commands().size() == 2);
  }
}

TEST_CASE("teleop: forward with depth unavailable is 503 standing still (nothing latched), 423 and a latch when already moving") {
  Fixture f(min_30cm());
  bool available = false;
  ObstacleScript depth(f.host.clock(), [&](std::int64_t) { return available ? at_cm(200) : ObstacleReading{}; });
  f.host.set_obstacle_source(&depth);
  auto r = f.post(move(0.3, 0.0));
  CHECK(r.status == 503);
  CHECK(r.body["code"] == "UNAVAILABLE");
  CHECK(r.body["reason"] == "depth_unavailable");
  CHECK_FALSE(f.host.estopped());
  CHECK(f.drive.commands().empty());

  available = true;
  REQUIRE(f.post(move(0.3, 0.0)).status == 200);
  f.host.advance(20ms);
  available = false;
  r = f.post(move(0.3, 0.0));  // the dead-man refresh of a moving robot
  CHECK(r.status == 423);
  CHECK(r.body["reason"] == "depth_unavailable");
  CHECK(f.host.estopped());
  CHECK_FALSE(f.drive.moving());
  CHECK(estop_reason(f.host).rfind("teleop: depth unavailable (no depth reading) while moving [depth available=false", 0) == 0);
}

TEST_CASE("teleop: camera.depth declared with no source refuses forward moves") {
  Fixture f({{"agent", {{"min_obstacle_m", 0.3}}}, {"camera", {{"depth", "synthetic"}}}});
  CHECK(f.post(move(0.3, 0.0)).status == 503);
  CHECK(f.post(move(-0.3, 0.0)).status == 200);
}

TEST_CASE("teleop: an obstacle appearing during a held forward move latches within 25 ms; checks every 25 ms") {
  Fixture f(min_30cm());
  ObstacleScript source(f.host.clock(), appearing(150, 25, 230'000));
  f.host.set_obstacle_source(&source);
  REQUIRE(f.post(move(0.5, 0.0)).status == 200);  // the dead-man: 500 ms
  f.host.advance(200ms);
  REQUIRE(f.post(move(0.5, 0.0)).status == 200);  // refreshed at 200 ms: the checks go on
  f.host.advance(100ms);
  CHECK(f.host.estopped());
  CHECK_FALSE(f.drive.moving());
  const auto events = f.drive.events();
  CHECK(events.back().halt);
  CHECK(events.back().t_us >= 230'000);
  CHECK(events.back().t_us <= 255'000);
  for (std::size_t i = 1; i < source.read_times.size(); ++i) CHECK(source.read_times[i] - source.read_times[i - 1] <= 25'000);
  CHECK(estop_reason(f.host).rfind("teleop: obstacle at 25.0 cm, below the minimum 30.0 cm while moving [depth "
                                   "available=true left_cm=25.0",
                                   0) == 0);
  CHECK(f.host.pending_tasks() == 0);  // on_estop disarmed the dead-man and the watch
}

TEST_CASE("teleop: depth going unavailable during a held forward move latches") {
  Fixture f(min_30cm());
  ObstacleScript source(f.host.clock(), [](std::int64_t now) {
    if (now < 120'000) return at_cm(150);
    ObstacleReading stale = at_cm(150);
    stale.available = false;  // vision still dates the last frame it had
    stale.timestamp_ms = 1'700'000'000'100;
    return stale;
  });
  f.host.set_obstacle_source(&source);
  REQUIRE(f.post(move_for(0.4, 0.0, 1000)).status == 200);
  f.host.advance(200ms);
  CHECK(f.host.estopped());
  CHECK(f.drive.events().back().t_us == 125'000);  // the first check after 120 ms
  CHECK(estop_reason(f.host).rfind("teleop: depth unavailable (stale: the last depth frame is 25 ms old) while moving", 0) == 0);
}

TEST_CASE("teleop: the watch ends with the move; nothing is checked while the robot stands") {
  Fixture f(min_30cm());
  ObstacleScript source(f.host.clock(), appearing(150, 10, 400'000));
  f.host.set_obstacle_source(&source);
  REQUIRE(f.post(move_for(0.4, 0.0, 300)).status == 200);
  f.host.advance(1s);  // the obstacle comes at 400 ms, after the move ended at 300 ms
  CHECK_FALSE(f.host.estopped());
  CHECK(f.host.pending_tasks() == 0);
  CHECK(source.read_times.back() < 300'000);
  // A stop ends the watch too (the obstacle went away again: the move may start).
  ObstacleScript clear(f.host.clock(), appearing(150, 150, 0));
  f.host.set_obstacle_source(&clear);
  REQUIRE(f.post(move(0.4, 0.0)).status == 200);
  CHECK(f.host.pending_tasks() == 2);  // the dead-man and the watch
  CHECK(f.post({{"type", "stop"}}).status == 200);
  CHECK(f.host.pending_tasks() == 0);
}

TEST_CASE("teleop: a minimum but no depth (no source, camera.depth not declared): a forward move runs unwatched") {
  Fixture f(min_30cm());
  REQUIRE(f.post(move(0.4, 0.0)).status == 200);
  CHECK(f.host.pending_tasks() == 1);  // the dead-man only: every reading would be Clear
  CHECK(f.post({{"type", "stop"}}).status == 200);
  // A source offered later is watched from the next move on.
  ObstacleScript clear(f.host.clock(), appearing(150, 150, 0));
  f.host.set_obstacle_source(&clear);
  REQUIRE(f.post(move(0.4, 0.0)).status == 200);
  CHECK(f.host.pending_tasks() == 2);  // the dead-man and the watch
}
