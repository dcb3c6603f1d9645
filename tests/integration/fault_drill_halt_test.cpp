// Fault drill: an actuating driver whose halt() is slow (2 s), never returns, or throws out of its noexcept hook,
// next to the sim drive. The e-stop still latches at once, POST /api/stop answers within 500 ms naming the failing
// driver (halt_pending / halt_failed) while the sim drive reports halted, motion stays refused, and no audit entry
// is lost.
#include <doctest/doctest.h>

#include <string>

#include "fault_drill.hpp"
#include "rcand_process.hpp"

using namespace rcand::test;
using nlohmann::json;

namespace {

const std::string kHaltDrillMove = R"({"type":"move","linear":0.3,"angular":0.0,"duration_ms":5000})";

json config_with_bad_driver(const std::string& fault) {
  auto config = sim_config();
  config["drivers"].push_back(
      {{"id", "bad0"}, {"protocol", "org.rcand.test.faulty_drive"}, {"hook", "halt"}, {"fault", fault}, {"slow_ms", 2000}});
  return config;
}

json driver_entry(const json& stop, const std::string& id) {
  for (const auto& entry : stop.value("drivers", json::array()))
    if (entry.value("id", "") == id) return entry;
  FAIL("no driver " << id << " in " << stop.dump());
  return {};
}

void run_drill(const std::string& fault, const std::string& expected_state) {
  CAPTURE(fault);
  RcandProcess rcand(config_with_bad_driver(fault), {plugin_dir(), test_plugin_dir() / "faults"});
  const std::string tag = "halt-" + fault + "-";
  CHECK(drill::tagged(rcand, "POST", "/api/action", "user-token", kHaltDrillMove, tag + "move").status == 200);

  const auto stop = drill::stop_within_limit(rcand, tag + "stop");
  CHECK_FALSE(stop.body.value("motors_stopped", true));  // not every driver confirmed
  const auto bad = driver_entry(stop.body, "bad0");
  CHECK(bad.value("halted", true) == false);
  CHECK(bad.value("state", "") == expected_state);
  CHECK(bad.value("error", "").find("halt()") != std::string::npos);
  for (const std::string good : {"drive0", "gripper0"}) {
    const auto entry = driver_entry(stop.body, good);
    CHECK(entry.value("halted", false));  // the other halts were neither delayed nor skipped
    CHECK(entry.value("state", "") == "halted");
  }
  // The sim drive's motors are at zero right after the answer.
  const auto drive = rcand.json("GET", "/api/drivers/drive0", "guest-token");
  CHECK(drive["status"].value("moving", true) == false);

  CHECK(rcand.json("GET", "/api/estop", "guest-token").value("estopped", false));
  CHECK(drill::tagged(rcand, "POST", "/api/action", "user-token", kHaltDrillMove, tag + "refused").status == 423);
  const auto again = drill::stop_within_limit(rcand, tag + "stop-again");  // a halt still running delays nothing
  CHECK(driver_entry(again.body, "bad0").value("state", "") == expected_state);
  if (fault == "throw") {  // a driver that cannot halt stays out of service after a clear
    const auto status = rcand.json("GET", "/api/status", "guest-token");
    for (const auto& driver : status["drivers"])
      if (driver["id"] == "bad0") CHECK(driver["state"] == "failed");
  }
  drill::check_audit_complete(rcand, {tag + "move", tag + "stop", tag + "refused", tag + "stop-again"});
}

}  // namespace

TEST_CASE("fault drill: a driver whose halt() takes 2 s delays neither the stop's answer nor the other halts") {
  run_drill("slow", "halt_pending");
}

TEST_CASE("fault drill: a driver whose halt() never returns is reported, and the robot stays stoppable") {
  run_drill("hang", "halt_pending");
}

TEST_CASE("fault drill: a driver whose halt() throws (std::terminate in noexcept) is contained and reported") {
  run_drill("throw", "halt_failed");
}
