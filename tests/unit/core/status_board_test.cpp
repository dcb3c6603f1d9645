// The status snapshot (issue 14 item 6): published statuses are served without calling plugin code, silent
// instances are asked on the status thread, ones that neither publish nor answer show as stale, the e-stop variant
// is picked live, and the document keeps every key GET /api/status always had.
#include <doctest/doctest.h>

#include <rcand/sdk/testing/manual_clock.hpp>

#include <atomic>
#include <chrono>
#include <future>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>

#include "kernel/plugins/instance_context.hpp"
#include "kernel/safety/estop.hpp"
#include "kernel/safety/kernel_motion_gate.hpp"
#include "kernel/status/status_board.hpp"
#include "rcand/sdk/interfaces/pose_source.hpp"

using namespace rcand;
using namespace rcand::kernel;
using namespace std::chrono_literals;
using nlohmann::json;

namespace {

constexpr auto kWait = 10s;  // generous: a loaded CI machine, never a sleep

// nav's PoseSource service as the test sets it: the board reads "pose" and "nav_running" from it at each rebuild.
struct FakePose final : sdk::PoseSource {
  mutable std::mutex mutex;
  sdk::PoseReading reading{true, {0.0, 0.0, 0.0}, false};
  mutable std::atomic<int> reads{0};
  sdk::PoseReading read() const noexcept override {
    ++reads;
    std::lock_guard lock(mutex);
    return reading;
  }
  void set(sdk::Pose2d pose, bool busy) {
    std::lock_guard lock(mutex);
    reading = {true, pose, busy};
  }
};

// A status() stand-in: counts calls, answers what the test set (nullopt: as one that throws or hangs).
struct Poll {
  std::mutex mutex;
  std::optional<json> answer;
  std::atomic<int> calls{0};
  std::function<std::optional<json>()> fn() {
    return [this] {
      ++calls;
      std::lock_guard lock(mutex);
      return answer;
    };
  }
  void set(std::optional<json> value) {
    std::lock_guard lock(mutex);
    answer = std::move(value);
  }
};

struct BoardRig {
  sdk::testing::ManualClock clock;
  ActuatorTable actuators;
  Estop estop{clock, actuators};
  KernelMotionGate gate{actuators, estop};
  sdk::ConfigView robot_config;
  KernelServices services{clock, estop, gate, robot_config, nullptr, "rcan://test/robot", {}};
  InstanceHealth nav_health, teleop_health, gripper_health, drive_health;
  InstanceContext nav{"org.rcand.nav", "nav", services, json::object(), nav_health};
  InstanceContext drive_context{"org.rcand.sim_drive", "drive0", services, json::object(), drive_health};
  Poll nav_poll, teleop_poll, gripper_poll, drive_poll;
  FakePose pose;
  std::unique_ptr<StatusBoard> board;

  // `with_pose`: nav offers its PoseSource, as it does in rcand once started.
  explicit BoardRig(bool with_pose = true) {
    clock.set_us(5'000'000);
    if (with_pose) REQUIRE(sdk::offer<sdk::PoseSource>(nav, pose));
    nav_poll.set(json{{"running", false}, {"pose", {{"x_m", 0.0}, {"y_m", 0.0}, {"heading_deg", 0.0}}}});
    teleop_poll.set(json{{"moving", false}});
    gripper_poll.set(std::nullopt);  // answers nothing, never publishes
    drive_poll.set(json{{"moving", false}});
    std::vector<StatusBoard::Source> sources{
        {"nav", false, {{"plugin", "org.rcand.nav"}}, &nav_health, nav_poll.fn()},
        {"teleop", false, {{"plugin", "org.rcand.teleop"}}, &teleop_health, teleop_poll.fn()},
        {"com.acme.gripper", false, {{"plugin", "com.acme.gripper"}}, &gripper_health, gripper_poll.fn()},
        {"drive0",
         true,
         {{"id", "drive0"}, {"protocol", "sim_diff_drive"}, {"plugin", "org.rcand.sim_drive"}, {"actuates", true}},
         &drive_health,
         drive_poll.fn()},
    };
    PluginHost no_plugins;
    auto fixed =
        StatusBoard::fixed_fields({"rcan://test/robot", "testbot", "rover"}, {"status", "nav", "teleop"}, no_plugins, "9.9.9");
    board = std::make_unique<StatusBoard>(std::move(sources), services, std::move(fixed), clock.now_us());
  }

  json body() const { return json::parse(*board->body()); }
  // The body once it includes every change made so far; answered by the status thread when a rebuild is due.
  json current() const {
    auto answered = std::make_shared<std::promise<std::string>>();
    auto future = answered->get_future();
    board->when_current([answered](std::shared_ptr<const std::string> body) { answered->set_value(*body); });
    REQUIRE(future.wait_for(kWait) == std::future_status::ready);
    return json::parse(future.get());
  }
  int polls() const { return nav_poll.calls + teleop_poll.calls + gripper_poll.calls + drive_poll.calls; }
};

std::set<std::string> keys_of(const json& object) {
  std::set<std::string> keys;
  for (const auto& [key, value] : object.items()) keys.insert(key);
  return keys;
}

}  // namespace

TEST_CASE("the document has exactly the keys GET /api/status always had, and asks every instance once at start") {
  BoardRig rig;
  rig.board->start();
  CHECK(rig.nav_poll.calls == 1);
  CHECK(rig.teleop_poll.calls == 1);
  CHECK(rig.gripper_poll.calls == 1);
  CHECK(rig.drive_poll.calls == 1);

  const json doc = rig.body();
  CHECK(keys_of(doc) == std::set<std::string>{"ruri", "name", "version", "rcan_version", "caps", "plugins", "state", "estopped",
                                              "uptime_s", "drivers", "capabilities", "nav_running", "pose"});
  CHECK(doc["ruri"] == "rcan://test/robot");
  CHECK(doc["name"] == "testbot");
  CHECK(doc["version"] == "9.9.9");
  CHECK(doc["rcan_version"] == std::string(kRcanVersion));
  CHECK(doc["caps"] == json{"status", "nav", "teleop"});
  CHECK(doc["plugins"] == json::array());
  CHECK(doc["state"] == "idle");
  CHECK(doc["estopped"] == false);
  CHECK(doc["uptime_s"] == 0);
  CHECK(doc["nav_running"] == false);
  CHECK(doc["pose"] == json{{"x_m", 0.0}, {"y_m", 0.0}, {"heading_deg", 0.0}});
  CHECK(doc["capabilities"]["teleop"] == json{{"plugin", "org.rcand.teleop"}, {"state", "ok"}, {"status", {{"moving", false}}}});
  CHECK(doc["capabilities"]["com.acme.gripper"] == json{{"plugin", "com.acme.gripper"}, {"state", "ok"}});
  REQUIRE(doc["drivers"].size() == 1);
  CHECK(doc["drivers"][0] == json{{"id", "drive0"},
                                  {"protocol", "sim_diff_drive"},
                                  {"plugin", "org.rcand.sim_drive"},
                                  {"actuates", true},
                                  {"state", "ok"}});
  CHECK(rig.board->document() == doc);
  CHECK(rig.board->robot_state() == "idle");
}

TEST_CASE("a published status is served without any status() call; nav's running and pose come from its PoseSource") {
  BoardRig rig;
  rig.board->start();
  const int asked = rig.polls();
  const json pose{{"x_m", 1.5}, {"y_m", -0.25}, {"heading_deg", 30.0}};
  rig.pose.set({1.5, -0.25, 30.0}, true);
  rig.nav.publish_status({{"running", true}, {"state", "driving"}});

  const json doc = rig.current();  // answered by the rebuild the publish asked for
  CHECK(doc["capabilities"]["nav"]["status"]["state"] == "driving");
  CHECK(doc["nav_running"] == true);
  CHECK(doc["state"] == "running");
  CHECK(doc["pose"] == pose);
  CHECK(rig.board->robot_state() == "running");
  CHECK(rig.polls() == asked);

  // Nine seconds later: nav kept publishing, so it is never asked; the silent ones are asked once a second.
  for (int step = 1; step <= 10; ++step) {
    rig.clock.advance(900ms);
    rig.pose.set({1.5, -0.25, 30.0}, step < 10);
    rig.nav.publish_status({{"running", step < 10}, {"step", step}});
    rig.board->refresh();
  }
  CHECK(rig.nav_poll.calls == 1);     // only the first round at start
  CHECK(rig.teleop_poll.calls == 6);  // at start, then whenever a second passed since: 1.8, 3.6, 5.4, 7.2, 9 s
  const json later = rig.body();
  CHECK(later["capabilities"]["nav"]["status"]["step"] == 10);
  CHECK(later["nav_running"] == false);
  CHECK(later["state"] == "idle");
  CHECK(later["uptime_s"] == 9);
  CHECK(later["pose"] == pose);
}

TEST_CASE("the pose is read from the PoseSource at each rebuild, never per request") {
  BoardRig rig;
  rig.board->start();
  rig.board->stop();  // no rebuilds from here on (no tick either)
  const int reads = rig.pose.reads;
  CHECK(reads >= 1);  // the documents built so far
  for (int i = 0; i < 1000; ++i) (void)rig.board->body();
  (void)rig.current();
  (void)rig.board->document();
  (void)rig.board->robot_state();
  CHECK(rig.pose.reads == reads);  // serving reads nothing
}

TEST_CASE("nav's status JSON is not read for the top level; a failed nav's PoseSource is not found") {
  BoardRig rig;
  rig.board->start();
  const int reads = rig.pose.reads;
  // A status that says otherwise changes nothing at the top level: only the service counts.
  rig.nav.publish_status({{"running", true}, {"pose", {{"x_m", 9.0}, {"y_m", 9.0}, {"heading_deg", 9.0}}}});
  const json doc = rig.current();
  CHECK(doc["capabilities"]["nav"]["status"]["running"] == true);
  CHECK(doc["nav_running"] == false);
  CHECK(doc["pose"] == json{{"x_m", 0.0}, {"y_m", 0.0}, {"heading_deg", 0.0}});
  CHECK(rig.pose.reads > reads);  // the rebuild the publish asked for read it once more

  // nav failing hides its service: no pose and not running, as before the service existed.
  rig.pose.set({1.0, 2.0, 3.0}, true);
  rig.nav_health.mark_failed("handler threw");
  const json failed = rig.current();
  CHECK_FALSE(failed.contains("pose"));
  CHECK(failed["nav_running"] == false);
  CHECK(failed["state"] == "error");
}

TEST_CASE("without a PoseSource (no nav) the document has no pose and is never running") {
  BoardRig rig(false);
  rig.board->start();
  rig.nav.publish_status({{"running", true}, {"pose", {{"x_m", 1.0}, {"y_m", 0.0}, {"heading_deg", 0.0}}}});
  const json doc = rig.current();
  CHECK_FALSE(doc.contains("pose"));
  CHECK(doc["nav_running"] == false);
  CHECK(doc["state"] == "idle");
  CHECK(rig.board->robot_state() == "idle");

  // Offered later (nav started after the board, or a plugin found late): picked up at the next rebuild.
  rig.pose.set({0.5, 0.0, 0.0}, true);
  REQUIRE(sdk::offer<sdk::PoseSource>(rig.nav, rig.pose));
  rig.board->notify();
  rig.board->refresh();
  const json later = rig.body();
  CHECK(later["pose"] == json{{"x_m", 0.5}, {"y_m", 0.0}, {"heading_deg", 0.0}});
  CHECK(later["nav_running"] == true);
  CHECK(later["state"] == "running");
}

TEST_CASE("a silent instance is asked once a second on the status thread, not per read") {
  BoardRig rig;
  rig.board->start();
  CHECK(rig.teleop_poll.calls == 1);
  for (int i = 0; i < 1000; ++i) (void)rig.board->body();
  rig.board->refresh();  // nothing is due yet
  CHECK(rig.teleop_poll.calls == 1);

  rig.teleop_poll.set(json{{"moving", true}});
  rig.clock.advance(1100ms);
  rig.board->refresh();
  CHECK(rig.teleop_poll.calls == 2);
  CHECK(rig.body()["capabilities"]["teleop"]["status"]["moving"] == true);
  rig.board->refresh();
  CHECK(rig.teleop_poll.calls == 2);
}

TEST_CASE("an instance that neither publishes nor answers is stale with its age; one that stops publishing too") {
  BoardRig rig;
  rig.board->start();
  rig.nav.publish_status({{"running", false}, {"mark", "last words"}});
  (void)rig.current();
  rig.nav_poll.set(std::nullopt);  // from now on nav's status() answers nothing either

  rig.clock.advance(1500ms);
  rig.board->refresh();
  CHECK_FALSE(rig.body()["capabilities"]["nav"].contains("stale"));

  rig.clock.advance(1000ms);  // 2.5 s since nav's publish and since the gripper was first asked
  rig.board->refresh();
  const json doc = rig.body();
  const json& gripper = doc["capabilities"]["com.acme.gripper"];
  CHECK(gripper["stale"] == true);
  CHECK(gripper["age_ms"] == 2500);
  CHECK(gripper["state"] == "ok");  // stale is not failed: the state logic is as before
  CHECK_FALSE(gripper.contains("status"));
  const json& nav = doc["capabilities"]["nav"];
  CHECK(nav["stale"] == true);
  CHECK(nav["age_ms"] == 2500);
  CHECK(nav["status"]["mark"] == "last words");                  // the last value it gave, marked stale
  CHECK_FALSE(doc["capabilities"]["teleop"].contains("stale"));  // it answers when asked
  CHECK_FALSE(doc["drivers"][0].contains("stale"));
  CHECK(doc["state"] == "idle");

  rig.nav.publish_status({{"running", false}, {"mark", "back"}});
  const json back = rig.current();
  CHECK_FALSE(back["capabilities"]["nav"].contains("stale"));
  CHECK(back["capabilities"]["nav"]["status"]["mark"] == "back");
}

TEST_CASE("the e-stop flips estopped and state in body() at once, with no rebuild in between") {
  BoardRig rig;
  rig.board->start();
  rig.board->stop();  // no status thread any more: only the variant choice can change what body() says
  CHECK(rig.body()["estopped"] == false);
  CHECK(rig.body()["state"] == "idle");

  rig.estop.latch("test", "unit");
  json latched = rig.body();
  CHECK(latched["estopped"] == true);
  CHECK(latched["state"] == "estop");
  CHECK(rig.board->robot_state() == "estop");
  CHECK(rig.board->document()["state"] == "estop");
  latched.erase("estopped");

  rig.estop.clear();
  json cleared = rig.body();
  CHECK(cleared["estopped"] == false);
  CHECK(cleared["state"] == "idle");
  cleared.erase("estopped");
  cleared["state"] = "estop";
  CHECK(cleared == latched);  // nothing else differs between the two variants
}

TEST_CASE("an instance marked failed shows at the next read through when_current, with no notify") {
  BoardRig rig;
  rig.board->start();
  rig.teleop_health.mark_failed("handler threw: boom");
  const json doc = rig.current();
  CHECK(doc["capabilities"]["teleop"] ==
        json{{"plugin", "org.rcand.teleop"}, {"state", "failed"}, {"reason", "handler threw: boom"}});
  CHECK(doc["state"] == "error");
  CHECK(rig.board->robot_state() == "error");

  rig.clock.advance(5s);
  const int asked = rig.teleop_poll.calls;
  rig.board->refresh();
  CHECK(rig.teleop_poll.calls == asked);  // a failed instance is never asked again
  CHECK_FALSE(rig.body()["capabilities"]["teleop"].contains("stale"));

  rig.drive_health.mark_failed("halt threw");
  rig.board->notify();
  const json drivers = rig.current()["drivers"];
  CHECK(drivers[0]["state"] == "failed");
  CHECK(drivers[0]["reason"] == "halt threw");
}

TEST_CASE("a status reporting a fault makes its item and the robot error, with the fault made safe, until it clears") {
  BoardRig rig;
  rig.board->start();
  rig.nav.publish_status({{"running", false}, {"fault", "camera device /dev/video3 does not exist\n\xe2\x80\xae"}});
  json doc = rig.current();
  CHECK(doc["capabilities"]["nav"]["state"] == "error");
  CHECK(doc["capabilities"]["nav"]["reason"] == "camera device /dev/video3 does not exist??");
  CHECK(doc["state"] == "error");
  CHECK(rig.board->robot_state() == "error");

  rig.drive_context.publish_status({{"moving", false}, {"fault", std::string(5000, 'x')}});  // a driver, and a long fault
  doc = rig.current();
  CHECK(doc["drivers"][0]["state"] == "error");
  CHECK(doc["drivers"][0]["reason"].get<std::string>().size() <= StatusBoard::kFaultTextBytes);

  rig.nav.publish_status({{"running", false}, {"fault", nullptr}});  // null or "" is no fault
  rig.drive_context.publish_status({{"moving", false}, {"fault", ""}});
  doc = rig.current();
  CHECK(doc["capabilities"]["nav"]["state"] == "ok");
  CHECK_FALSE(doc["capabilities"]["nav"].contains("reason"));
  CHECK(doc["drivers"][0]["state"] == "ok");
  CHECK(doc["state"] == "idle");
  CHECK(rig.board->robot_state() == "idle");
}

TEST_CASE("publishes coalesce; a driver's published status keeps it fresh without being listed") {
  BoardRig rig;
  rig.board->start();
  for (int i = 0; i < 500; ++i) rig.drive_context.publish_status({{"moving", true}, {"n", i}});
  const json doc = rig.current();
  CHECK_FALSE(doc["drivers"][0].contains("status"));  // drivers are listed without their status, as before
  rig.clock.advance(1500ms);
  rig.board->refresh();
  CHECK(rig.drive_poll.calls == 2);  // published 1.5 s ago: asked once more
  rig.clock.advance(1000ms);
  rig.board->refresh();
  CHECK_FALSE(rig.body()["drivers"][0].contains("stale"));
}

TEST_CASE("a driver's publish that keeps its fault changes nothing shown: no reader waits for it; a new fault shows") {
  BoardRig rig;
  rig.board->start();
  rig.drive_context.publish_status({{"moving", true}, {"n", 0}});  // the first one counts
  (void)rig.current();
  for (int i = 1; i <= 20; ++i) rig.drive_context.publish_status({{"moving", true}, {"n", i}});  // a drive at 10 Hz
  // Shared, not a local by reference: were the answer ever queued, the status thread would give it after this case.
  auto answered = std::make_shared<std::promise<std::thread::id>>();
  auto answered_on = answered->get_future();
  rig.board->when_current([answered](std::shared_ptr<const std::string>) { answered->set_value(std::this_thread::get_id()); });
  REQUIRE(answered_on.wait_for(std::chrono::seconds(0)) == std::future_status::ready);
  CHECK(answered_on.get() == std::this_thread::get_id());  // at once, on this thread: there was no change to wait for
  rig.drive_context.publish_status({{"moving", true}, {"fault", "encoder lost"}});
  CHECK(rig.current()["drivers"][0]["reason"] == "encoder lost");
  rig.drive_context.publish_status({{"moving", true}});
  CHECK(rig.current()["drivers"][0]["state"] == "ok");
}

TEST_CASE("after a plugin reload the new context's publishes feed the same entry, never polled while they come") {
  BoardRig rig;
  rig.board->start();
  const int asked = rig.nav_poll.calls;
  // The reload destroyed nav's context and made another over the same instance (the same health).
  InstanceContext reloaded{"org.rcand.nav", "nav", rig.services, json::object(), rig.nav_health};
  reloaded.publish_status({{"running", false}, {"version", 2}});
  CHECK(rig.current()["capabilities"]["nav"]["status"]["version"] == 2);
  for (int step = 1; step <= 5; ++step) {
    rig.clock.advance(900ms);
    reloaded.publish_status({{"running", false}, {"version", 2}, {"step", step}});
    rig.board->refresh();
  }
  CHECK(rig.nav_poll.calls == asked);  // kept fresh by its publishes alone
  CHECK(rig.body()["capabilities"]["nav"]["status"]["step"] == 5);
}

TEST_CASE("stop is idempotent; afterwards publishes are dropped and when_current answers at once") {
  BoardRig rig;
  rig.board->start();
  const std::string before = *rig.board->body();
  rig.board->stop();
  rig.board->stop();
  rig.nav.publish_status({{"running", true}});
  CHECK(*rig.board->body() == before);
  CHECK(rig.current()["nav_running"] == false);
  rig.board.reset();
  rig.estop.latch("after the board", "unit");  // its listener outlives it harmlessly
  CHECK(rig.estop.latched());
}
