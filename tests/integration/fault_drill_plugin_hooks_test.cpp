// Fault drill: a capability plugin that throws, hangs or returns garbage in each lifecycle hook and in its request
// handler (tests/plugins/faults). In every case rcand comes up and keeps serving, the faulty capability is reported,
// the other capabilities keep working, POST /api/stop answers within 500 ms, and no audit entry is lost.
#include <doctest/doctest.h>

#include <chrono>
#include <future>
#include <string>

#include "fault_drill.hpp"
#include "rcand_process.hpp"

using namespace rcand::test;
using nlohmann::json;
using namespace std::chrono_literals;

namespace {

const std::string kCapability = "org.rcand.test.faulty";
const std::string kWork = "/api/cap/" + kCapability + "/work";
const std::string kShortMove = R"({"type":"move","linear":0.2,"angular":0.0,"duration_ms":200})";

json faulty_config(const std::string& hook, const std::string& fault) {
  auto config = sim_config();
  config["rcan_protocol"]["capabilities"].push_back(kCapability);
  config["runtime"]["capabilities"][kCapability] = {{"hook", hook}, {"fault", fault}};
  config["runtime"]["plugin_start_timeout_ms"] = 500;
  config["runtime"]["handler_timeout_ms"] = 500;
  return config;
}

struct Case {
  std::string hook, fault;
  int work_status;          // what POST .../work answers
  bool failed_after_start;  // the capability is out of service once rcand serves
  bool failed_after_stop;   // ... once a stop ran (on_estop faults)
};

void run_drill(const Case& c) {
  CAPTURE(c.hook);
  CAPTURE(c.fault);
  RcandProcess rcand(faulty_config(c.hook, c.fault), {plugin_dir(), test_plugin_dir() / "faults"});
  const std::string tag = "drill-" + c.hook + "-" + c.fault + "-";
  std::vector<std::string> audited;
  auto id = [&](const std::string& name) {
    audited.push_back(tag + name);
    return audited.back();
  };
  auto capability_state = [&] {
    const auto status = rcand.json("GET", "/api/status", "owner-token");
    return status["capabilities"][kCapability].value("state", "missing");
  };

  // A hung status() is failed by the first read that finds it still running StatusReader::kHungAfter after it began.
  if (c.failed_after_start) CHECK(eventually([&] { return capability_state() == "failed"; }, 20s, 100ms));
  CHECK(capability_state() == (c.failed_after_start ? "failed" : "ok"));
  const auto work = drill::tagged(rcand, "POST", kWork, "owner-token", "{}", id("work"));
  CHECK(work.status == c.work_status);
  if (work.status >= 300) CHECK(work.body.contains("code"));  // an error always has a code
  int status = 0;
  rcand.json("GET", "/api/status", "guest-token", "", &status);
  CHECK(status == 200);
  CHECK(drill::tagged(rcand, "POST", "/api/action", "user-token", kShortMove, id("move")).status == 200);  // teleop unaffected

  const auto stop = drill::stop_within_limit(rcand, id("stop"));
  CHECK(stop.body.value("motors_stopped", false));
  CHECK(drill::tagged(rcand, "POST", "/api/action", "user-token", kShortMove, id("refused")).status == 423);
  drill::stop_within_limit(rcand, id("stop-again"));  // a hook still hung from the first stop delays nothing
  // on_estop() runs after the answer (the stop waits for the halts only): its fault is reported just after.
  if (c.failed_after_stop) CHECK(eventually([&] { return capability_state() == "failed"; }, 20s, 10ms));
  CHECK(capability_state() == (c.failed_after_stop ? "failed" : "ok"));
  drill::check_audit_complete(rcand, audited);
}

}  // namespace

TEST_CASE("fault drill: a plugin whose register() never returns: rcand starts without it and stays stoppable") {
  auto config = sim_config();
  config["rcan_protocol"]["capabilities"].push_back("org.rcand.test.hangs_in_register");
  config["runtime"]["plugin_start_timeout_ms"] = 500;
  RcandProcess rcand(config, {plugin_dir(), test_plugin_dir() / "hangs_in_register"});
  const auto status = rcand.json("GET", "/api/status", "owner-token");
  const auto& hung = status["capabilities"]["org.rcand.test.hangs_in_register"];
  CHECK(hung["state"] == "failed");
  CHECK(hung.value("reason", "").find("register() did not return within 500 ms") != std::string::npos);
  CHECK(drill::tagged(rcand, "POST", "/api/action", "user-token", kShortMove, "register-hang-move").status == 200);
  drill::stop_within_limit(rcand, "register-hang-stop");
  drill::check_audit_complete(rcand, {"register-hang-move", "register-hang-stop"});
  CHECK(rcand.stop() == 0);
}

TEST_CASE("fault drill: plugin factory faults (throws, hangs, returns nothing)") {
  for (const std::string fault : {"throw", "hang", "garbage"}) run_drill({"factory", fault, 503, true, true});
}

TEST_CASE("fault drill: plugin start() faults (throws, hangs)") {
  for (const std::string fault : {"throw", "hang"}) run_drill({"start", fault, 503, true, true});
}

TEST_CASE("fault drill: plugin routes() faults (throws, hangs, returns unusable routes)") {
  for (const std::string fault : {"throw", "hang", "garbage"}) run_drill({"routes", fault, 503, true, true});
}

TEST_CASE(
    "fault drill: request handler faults (throws: 500 and stays in service, hangs: 503 at the timeout, invalid answer: 500)") {
  run_drill({"handler", "throw", 500, false, false});  // docs/protocol.md §7.16: a throw fails the request, not the capability
  run_drill({"handler", "hang", 503, false, true});
  run_drill({"handler", "garbage", 500, false, false});
}

TEST_CASE("fault drill: status() faults (throws, invalid UTF-8, hangs) never break GET /api/status") {
  run_drill({"status", "throw", 200, false, false});
  run_drill({"status", "garbage", 200, false, false});
  run_drill({"status", "hang", 503, true, true});  // a GET /api/status 2 s on finds it hung and fails it
}

TEST_CASE("fault drill: status() hanging in a capability and a driver holds no I/O thread: stops answer meanwhile") {
  auto config = faulty_config("status", "hang");
  config["drivers"].push_back(
      {{"id", "bad0"}, {"protocol", "org.rcand.test.faulty_drive"}, {"hook", "status"}, {"fault", "hang"}});
  RcandProcess rcand(config, {plugin_dir(), test_plugin_dir() / "faults"});
  // More status readers than rcand has I/O threads, all at once: inline status() calls would hold every thread.
  std::vector<std::future<drill::Answer>> readers;
  for (int i = 0; i < 3; ++i) {
    readers.push_back(std::async(std::launch::async, [&rcand, i] {
      return drill::tagged(rcand, "GET", "/api/status", "guest-token", "", "status-reader-" + std::to_string(i));
    }));
    readers.push_back(std::async(std::launch::async, [&rcand, i] {
      return drill::tagged(rcand, "GET", "/api/drivers/bad0", "guest-token", "", "driver-reader-" + std::to_string(i));
    }));
  }
  drill::stop_within_limit(rcand, "status-hang-stop");
  for (auto& reader : readers) {
    const auto answer = reader.get();
    CHECK(answer.status == 200);
    CHECK(answer.took < std::chrono::seconds(5));
  }
  CHECK(eventually(
      [&] { return rcand.json("GET", "/api/status", "guest-token")["capabilities"][kCapability]["state"] == "failed"; }, 20s,
      100ms));
  CHECK(eventually([&] { return rcand.json("GET", "/api/drivers/bad0", "guest-token")["state"] == "failed"; }, 20s, 100ms));
  const auto status = rcand.json("GET", "/api/status", "guest-token");
  CHECK(status["capabilities"][kCapability].value("reason", "").find("status() did not return") != std::string::npos);
  const auto driver = rcand.json("GET", "/api/drivers/bad0", "guest-token");
  CHECK(driver["state"] == "failed");
  CHECK_FALSE(driver.contains("status"));
  CHECK(rcand.json("GET", "/api/drivers/drive0", "guest-token")["status"].is_object());  // the others still answer
  drill::stop_within_limit(rcand, "status-hang-stop-again");
  drill::check_audit_complete(rcand, {"status-hang-stop", "status-hang-stop-again"});
  CHECK(rcand.stop() == 0);  // exits normally: the hung status() threads are left behind, not joined
}

TEST_CASE("fault drill: on_estop() faults (throws out of noexcept, hangs) never hold up the stop") {
  run_drill({"on_estop", "throw", 200, false, true});
  run_drill({"on_estop", "hang", 200, false, false});
}

TEST_CASE("fault drill: a shutdown() hook that hangs or throws cannot keep rcand from exiting cleanly after the motors stopped") {
  for (const std::string fault : {"hang", "throw"}) {
    CAPTURE(fault);
    RcandProcess rcand(faulty_config("shutdown", fault), {plugin_dir(), test_plugin_dir() / "faults"});
    const std::string tag = "drill-shutdown-" + fault + "-";
    CHECK(drill::tagged(rcand, "POST", "/api/action", "user-token", kShortMove, tag + "move").status == 200);
    drill::stop_within_limit(rcand, tag + "stop");
    drill::check_audit_complete(rcand, {tag + "move", tag + "stop"});
    const auto start = std::chrono::steady_clock::now();
    CHECK(rcand.stop() == 0);  // neither the shutdown watchdog's exit 1 nor an abort
    CHECK(std::chrono::steady_clock::now() - start < std::chrono::seconds(12));
    const std::string expected = fault == "hang" ? "shutdown() did not return within 2000 ms; left running"
                                                 : "shutdown() threw: fault drill: shutdown throws";
    CHECK_MESSAGE(rcand.stderr_text().find(expected) != std::string::npos, rcand.stderr_text());
  }
}
