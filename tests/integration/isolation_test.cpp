// Process isolation (issue 34): a capability configured `isolation: process` runs in rcand-plugin-host. Its fixture
// (tests/plugins/crasher) segfaults, aborts, leaks past its memory limit, spins in a handler or closes its channel on
// request; in each case rcand stays up and stoppable within the 500 ms MUST, the other capabilities keep serving, the
// drive the capability moved is halted by rcand, its routes answer 503 with the reason, the death is audited, and the
// capability comes back in a new process. Five deaths within a minute leave it failed.
#include <doctest/doctest.h>

#include <fcntl.h>
#include <stdlib.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <string>

#include "fault_drill.hpp"
#include "rcand_process.hpp"

using namespace rcand::test;
using nlohmann::json;
using namespace std::chrono_literals;

namespace {

const std::string kCapability = "org.rcand.test.crasher";
const std::string kBase = "/api/cap/" + kCapability;
const std::string kShortMove = R"({"type":"move","linear":0.2,"angular":0.0,"duration_ms":200})";

json crasher_config(json settings = json::object()) {
  auto config = sim_config();
  config["rcan_protocol"]["capabilities"].push_back(kCapability);
  config["runtime"]["capabilities"][kCapability] = std::move(settings);
  config["runtime"]["handler_timeout_ms"] = 1000;
  return config;
}

struct Robot {
  RcandProcess rcand;
  explicit Robot(json settings = json::object())
      : rcand(crasher_config(std::move(settings)), {plugin_dir(), test_plugin_dir() / "crasher"}) {}

  // The pid the capability answers from; 0 while it does not answer.
  int capability_pid() const {
    int status = 0;
    const auto body = rcand.json("GET", kBase + "/pid", "owner-token", "", &status);
    return status == 200 ? body.value("pid", 0) : 0;
  }
  json capability_status() const { return rcand.json("GET", "/api/status", "owner-token")["capabilities"][kCapability]; }
  json drive() const { return drive_status(rcand); }
  bool drive_halted_by_rcand() const {
    const auto drive_now = drive();
    const auto& events = drive_now["timeline"];
    return drive_now.value("left", 1.0) == 0.0 && !events.empty() && events.back().value("cause", "") == "halt";
  }
  void start_driving() const {
    int status = 0;
    rcand.json("POST", kBase + "/drive", "owner-token", "{}", &status);
    REQUIRE(status == 200);
    REQUIRE(drive().value("left", 0.0) == doctest::Approx(0.5));
  }
  bool audited_death() const {
    const auto audit = rcand.json("GET", "/api/audit?limit=10000", "owner-token");
    for (const auto& entry : audit.value("entries", json::array()))
      if (entry.value("event", "").find(kCapability + " process died") != std::string::npos) return true;
    return false;
  }
};

// One crash of kind `how`: what every crash must leave behind.
void crash_and_recover(const std::string& how, const std::string& reason_part, json settings = json::object()) {
  CAPTURE(how);
  Robot robot(std::move(settings));
  const int first_pid = robot.capability_pid();
  REQUIRE(first_pid > 0);
  CHECK(first_pid != robot.rcand.pid());
  robot.start_driving();

  const auto crash =
      drill::tagged(robot.rcand, "POST", kBase + "/crash", "owner-token", json{{"how", how}}.dump(), "crash-" + how);
  if (how != "close") {  // closing its channel answers first; every other crash ends the request with its process
    CHECK(crash.status == 503);
    CHECK(crash.body.value("code", "") == "UNAVAILABLE");
    CHECK(crash.body.value("reason", "").find(reason_part) != std::string::npos);  // the request waiting says why
  }
  // rcand halted the drive the capability moved, and said why the capability is down.
  CHECK(eventually([&] { return robot.drive_halted_by_rcand(); }, 10s, 10ms));
  CHECK(eventually([&] { return robot.audited_death(); }, 10s, 10ms));
  const std::string logged = robot.rcand.stderr_text();
  CHECK_MESSAGE(logged.find(reason_part) != std::string::npos, "rcand's log does not say '" << reason_part << "': " << logged);

  // rcand itself and the other capabilities never stopped serving.
  CHECK(drill::tagged(robot.rcand, "POST", "/api/action", "user-token", kShortMove, "move-" + how).status == 200);
  drill::stop_within_limit(robot.rcand, "stop-" + how);
  CHECK(robot.rcand.request("POST", "/api/estop/clear", "owner-token").status == 200);

  // The capability is back, in a new process, and moves the drive again through rcand's gate.
  CHECK(eventually([&] { return robot.capability_pid() > 0; }, 20s, 10ms));
  CHECK(robot.capability_pid() != first_pid);
  robot.start_driving();
  CHECK(robot.capability_status()["status"]["process"].value("restarts", 0) == 1);
}

}  // namespace

TEST_CASE("isolation: an isolated capability serves from its own process and moves motors only through rcand's gate") {
  Robot robot;
  const int pid = robot.capability_pid();
  CHECK(pid > 0);
  CHECK(pid != robot.rcand.pid());
  const auto status = robot.capability_status();
  CHECK(status.value("state", "") == "ok");
  CHECK(status["status"]["process"].value("pid", 0) == pid);
  CHECK(status["status"]["process"].value("isolation", "") == "process");

  robot.start_driving();
  drill::stop_within_limit(robot.rcand, "stop-isolated");
  CHECK(robot.drive().value("left", 1.0) == 0.0);
  // The capability's on_estop() ran in its process; its published status says so.
  CHECK(eventually([&] { return robot.capability_status()["status"].value("estops", 0) == 1; }, 10s, 10ms));
  // Latched: rcand refuses the motion route before it reaches the process; the mirror of the latch there agrees.
  int refused = 0;
  robot.rcand.json("POST", kBase + "/drive", "owner-token", "{}", &refused);
  CHECK(refused == 423);
  CHECK(robot.rcand.json("GET", kBase + "/pid", "owner-token").value("latched", false));
  // A throwing handler fails that request only, as in process.
  CHECK(robot.rcand.request("POST", "/api/estop/clear", "owner-token").status == 200);
  int thrown = 0;
  robot.rcand.json("POST", kBase + "/crash", "owner-token", R"({"how":"throw"})", &thrown);
  CHECK(thrown == 500);
  CHECK(robot.capability_pid() == pid);
  // Counted as in process (docs/protocol.md §7.16), in the status snapshot once it is rebuilt.
  CHECK(eventually([&] { return robot.capability_status().value("handler_errors", 0) == 1; }, 10s, 10ms));

  // rcand's shutdown reaches the capability's own shutdown() in its process, whose log line rcand writes.
  CHECK(robot.rcand.stop() == 0);
  CHECK(robot.rcand.stderr_text().find("crasher shutdown() ran in process " + std::to_string(pid)) != std::string::npos);
}

TEST_CASE("isolation: the capability's process has less than rcand: no privileges, and a filter on what it may call") {
  Robot robot;
  const auto privileges = robot.rcand.json("GET", kBase + "/privileges", "owner-token");
  CHECK(privileges.value("NoNewPrivs", "") == "1");
  CHECK(privileges.value("CapEff", "") == "0000000000000000");
  CHECK(privileges.value("Seccomp", "") == "2");  // a filter
  const auto attempt = [&](const std::string& what) {
    return robot.rcand.json("POST", kBase + "/try", "owner-token", json{{"what", what}}.dump()).value("errno", -1);
  };
  CHECK(attempt("read_rcand") == EPERM);
  CHECK(attempt("signal_rcand") == EPERM);
  CHECK(attempt("signal_group") == EPERM);
  CHECK(attempt("inet_socket") == EPERM);  // its manifest does not say it needs the network
  CHECK(attempt("unix_socket") == 0);
  CHECK(robot.capability_pid() > 0);  // refused, not killed

  // The robot's config overrides the manifest: in rcand's process, the same attempts are allowed (the checks above
  // are the filter's doing).
  Robot in_process(json{{"isolation", "in_process"}});
  CHECK(in_process.capability_pid() == in_process.rcand.pid());
  for (const char* what : {"signal_group", "inet_socket"}) {
    CAPTURE(what);
    CHECK(in_process.rcand.json("POST", kBase + "/try", "owner-token", json{{"what", what}}.dump()).value("errno", -1) == 0);
  }
}

TEST_CASE("isolation: the capability's process opens only the devices its manifest needs, and none of rcand's files") {
  // A pseudo-terminal stands for a serial port, as the serial emulators' do.
  const int master = ::posix_openpt(O_RDWR | O_NOCTTY | O_CLOEXEC);
  REQUIRE(master >= 0);
  REQUIRE((::grantpt(master) == 0 && ::unlockpt(master) == 0));
  const std::string serial_port = ::ptsname(master);
  TempDir dir;
  const auto plain_file = dir.write("plain.txt", "not a device");
  const auto opened = [](const RcandProcess& rcand, const std::filesystem::path& path, bool read_only = false) {
    const json attempt{{"what", "open"}, {"path", path.string()}, {"read_only", read_only}};
    return rcand.json("POST", kBase + "/try", "owner-token", attempt.dump()).value("errno", -1);
  };

  Robot robot;
  const auto sandbox = robot.capability_status()["status"]["process"]["sandbox"];
  INFO(sandbox.dump());
  if (sandbox.value("devices", "") != "restricted") {
    // A kernel without Landlock: said in the status (and logged), never silently.
    CHECK(sandbox.value("devices", "") == "unrestricted");
    CHECK(!sandbox.value("reason", "").empty());
    MESSAGE("SKIPPED the file checks: " << sandbox.dump());
    ::close(master);
    return;
  }
  CHECK(sandbox["device_classes"] == json::array());
  CHECK(sandbox.value("rcand_files_hidden", 0) >= 4);  // its config, its JWT secret, its state dir, /proc/<rcand>
  CHECK(opened(robot.rcand, serial_port) == EACCES);   // its manifest does not say it needs serial ports
  CHECK(opened(robot.rcand, "/dev/null") == 0);
  CHECK(opened(robot.rcand, "/dev/urandom") == 0);
  CHECK(opened(robot.rcand, plain_file) == 0);  // files outside /dev as before, beside rcand's own
  // rcand's own files: its config (written beside the JWT secret and the state dir), the secret, the latch's state,
  // and rcand's memory and environment through /proc.
  const auto& own = robot.rcand.dir().path();
  for (const auto& file : {own / "robot.rcan.yaml", own / "jwt.secret"}) {
    CAPTURE(file);
    CHECK(opened(robot.rcand, file, true) == EACCES);
  }
  CHECK(opened(robot.rcand, robot.rcand.dir().write("state/written-since", "in rcand's state dir"), true) == EACCES);
  const std::string rcand_proc = "/proc/" + std::to_string(robot.rcand.pid());
  CHECK(opened(robot.rcand, rcand_proc + "/environ", true) == EACCES);
  CHECK(opened(robot.rcand, rcand_proc + "/mem", true) == EACCES);
  CHECK(opened(robot.rcand, "/proc/self/status", true) == 0);  // its own
  CHECK(robot.capability_pid() > 0);

  // The same plugin whose manifest entry says it needs serial ports.
  auto manifest = json::parse(std::ifstream(test_plugin_dir() / "crasher" / "crasher.json"));
  manifest["provides"][0]["isolation_needs"] = {"serial"};
  const auto plugin = dir.write("crasher/crasher.json", manifest.dump()).parent_path();
  std::filesystem::copy_file(test_plugin_dir() / "crasher" / manifest["library"].get<std::string>(),
                             plugin / manifest["library"].get<std::string>());
  RcandProcess serial(crasher_config(), {plugin_dir(), plugin});
  CHECK(serial.json("GET", "/api/status",
                    "owner-token")["capabilities"][kCapability]["status"]["process"]["sandbox"]["device_classes"] ==
        json{"serial"});
  CHECK(opened(serial, serial_port) == 0);
  CHECK(opened(serial, "/dev/null") == 0);
  CHECK(opened(serial, serial.dir().path() / "robot.rcan.yaml", true) == EACCES);

  // In rcand's own process, the same attempts are allowed: the refusals above are the sandbox's.
  Robot in_process(json{{"isolation", "in_process"}});
  CHECK(opened(in_process.rcand, serial_port) == 0);
  CHECK(opened(in_process.rcand, in_process.rcand.dir().path() / "robot.rcan.yaml", true) == 0);
  ::close(master);
}

TEST_CASE("isolation: a host flooding rcand with actuator calls has those past 64 in flight refused, named") {
  auto config = crasher_config();
  config["drivers"][0]["halt_delay_ms"] = 1000;  // the fixture's first call, a halt, holds rcand's calls worker
  RcandProcess rcand(config, {plugin_dir(), test_plugin_dir() / "crasher"});
  int status = 0;
  rcand.json("POST", kBase + "/flood", "owner-token", R"({"calls":150})", &status);
  REQUIRE(status == 200);
  json result;
  REQUIRE(eventually([&] { return (result = rcand.json("GET", kBase + "/flood", "owner-token")).value("finished", false); }, 30s,
                     20ms));
  MESSAGE("flood: " << result.dump());
  CHECK(result.value("refused", 0) >= 1);  // refused at once with the cap's reason, never queued without bound
  CHECK(result.value("ok", 0) >= 63);      // those under the cap were answered
  CHECK(result.value("other", -1) == 0);
  CHECK(result.value("ok", 0) + result.value("refused", 0) == 150);
  CHECK(rcand.json("GET", kBase + "/pid", "owner-token").value("pid", 0) > 0);  // the host lives on
}

TEST_CASE("isolation: under the packaged unit's restrictions (no capabilities, capset refused) the host still starts") {
  auto config = crasher_config();
  config["runtime"]["plugin_paths"] = {plugin_dir().string(), (test_plugin_dir() / "crasher").string()};
  RcandProcess rcand(config, {RCAND_UNIT_RESTRICTIONS}, "127.0.0.1");
  int status = 0;
  const auto privileges = rcand.json("GET", kBase + "/privileges", "owner-token", "", &status);
  INFO(rcand.stderr_text());
  REQUIRE(status == 200);
  CHECK(privileges.value("CapEff", "") == "0000000000000000");
  CHECK(privileges.value("Seccomp", "") == "2");
  CHECK(rcand.json("POST", kBase + "/try", "owner-token", R"({"what":"signal_rcand"})").value("errno", -1) == EPERM);
}

TEST_CASE("isolation: a segfault ends only the capability's process") {
  crash_and_recover("segfault", "killed by signal 11 (SIGSEGV)");
}

TEST_CASE("isolation: an abort ends only the capability's process") {
  crash_and_recover("abort", "killed by signal 6 (SIGABRT)");
}

TEST_CASE("isolation: a leak is ended at the capability's memory limit") {
  crash_and_recover("leak", "over its limit of 96 MB (isolation_memory_mb)", {{"isolation_memory_mb", 96}});
}

TEST_CASE("isolation: a handler that spins is ended at the request timeout") {
  crash_and_recover("spin", "did not answer POST " + kBase + "/crash within 750 ms");
}

TEST_CASE("isolation: a capability that closes its channel is ended and started again") {
  crash_and_recover("close", "exited with status 0");
}

TEST_CASE("isolation: five deaths within a minute leave the capability failed with the last reason") {
  Robot robot;
  for (int death = 1; death <= 5; ++death) {
    CAPTURE(death);
    REQUIRE(eventually([&] { return robot.capability_pid() > 0; }, 20s, 10ms));
    robot.rcand.request("POST", kBase + "/crash", "owner-token", R"({"how":"abort"})");
  }
  CHECK(eventually([&] { return robot.capability_status().value("state", "") == "failed"; }, 10s, 10ms));
  const auto status = robot.capability_status();
  CHECK(status.value("reason", "").find("crash loop: 5 deaths within 60 s") != std::string::npos);
  CHECK(status.value("reason", "").find("SIGABRT") != std::string::npos);
  int answered = 0;
  robot.rcand.json("GET", kBase + "/pid", "owner-token", "", &answered);
  CHECK(answered == 503);
  CHECK(robot.rcand.request("GET", "/api/status", "guest-token").status == 200);
}

TEST_CASE("isolation: a capability whose start crashes fails with the reason, and rcand serves") {
  Robot robot(json{{"crash_on_start", true}});
  const auto status = robot.capability_status();
  CHECK(status.value("state", "") == "failed");
  CHECK(status.value("reason", "").find("SIGSEGV") != std::string::npos);
  drill::stop_within_limit(robot.rcand, "stop-after-failed-start");
}

TEST_CASE("isolation: the setting is checked where it is written") {
  auto config = crasher_config({{"isolation", "elsewhere"}});
  CHECK_THROWS_WITH_AS(RcandProcess(config, {plugin_dir(), test_plugin_dir() / "crasher"}),
                       doctest::Contains("expected \"process\" or \"in_process\""), std::runtime_error);
}

TEST_CASE("isolation: the arm capability in its own process moves the sim arm through rcand's gate, and reads it back") {
  auto config = sim_config();
  config["rcan_protocol"]["capabilities"] = {"status", "teleop", "arm"};
  config["physics"]["kinematics"] = json::array(
      {{{"joint", "shoulder"}, {"min_deg", -90}, {"max_deg", 90}}, {{"joint", "elbow"}, {"min_deg", 0}, {"max_deg", 135}}});
  config["drivers"].push_back({{"id", "arm0"}, {"protocol", "sim_arm"}});
  config["runtime"]["capabilities"]["arm"] = {{"isolation", "process"}};
  RcandProcess rcand(config);
  const json process = rcand.json("GET", "/api/status", "guest-token")["capabilities"]["arm"]["status"]["process"];
  REQUIRE(process.is_object());
  CHECK(process["pid"].get<long>() != rcand.pid());

  int status = 0;
  const auto moved =
      rcand.json("POST", "/api/action", "user-token", json{{"type", "arm_pose"}, {"joints", {{"shoulder", 30}}}}.dump(), &status);
  INFO(moved.dump());
  REQUIRE(status == 200);
  // The host's joint_states() answered by rcand's driver: the target it was given, through the gate.
  const auto joints = rcand.json("GET", "/api/arm/joints", "guest-token", "", &status);
  REQUIRE(status == 200);
  CHECK(joints["driver"] == "arm0");
  CHECK(joints["joints"][0]["joint"] == "shoulder");
  CHECK(joints["joints"][0]["target_deg"] == 30.0);

  // Latched in rcand: the motion route is refused there, before the host sees it.
  rcand.json("POST", "/api/stop", "guest-token", "{}", &status);
  REQUIRE(status == 200);
  rcand.json("POST", "/api/action", "user-token", json{{"type", "arm_pose"}, {"joints", {{"shoulder", 10}}}}.dump(), &status);
  CHECK(status == 423);
}
