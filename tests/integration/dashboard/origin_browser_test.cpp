// Issue 28 #2 in Debian's headless Chromium against a real rcand (tests/dashboard/origin_probe.mjs): a page of another
// origin (served by the probe from another loopback port) tries to clear the e-stop and drive with no-cors POSTs
// (text/plain bodies: no preflight) and to watch telemetry over a WebSocket; so does a page whose name resolves to the
// robot (DNS rebinding, evil.test mapped to 127.0.0.1). In auth mode open and in tokens mode the robot refuses all of
// it (403, logged) and stays latched and still; the robot's own page, as reached by its address, still does all three.
#include <doctest/doctest.h>

#include <filesystem>
#include <sstream>

#include "node_dir.hpp"
#include "rcand_process.hpp"

namespace fs = std::filesystem;
using nlohmann::json;
using namespace rcand::test;

namespace {

// What the probe's page saw: {"page", "clear", "move", "ws", "frames"} (see origin_probe.mjs).
json probe(const std::string& page, const RcandProcess& robot, const std::string& robot_url, const std::string& token = "") {
  const fs::path node_dir = prepared_node_dir();
  const auto run = run_tool("/usr/bin/node", {(node_dir / "origin_probe.mjs").string(), page, robot_url, token});
  INFO("origin_probe.mjs ", page, ":\n", run.out, run.err, "\nrcand:\n", robot.stderr_text());
  REQUIRE(run.exit_code == 0);
  std::istringstream lines(run.out);
  std::string line, last;
  while (std::getline(lines, line))
    if (!line.empty()) last = line;
  const json seen = json::parse(last, nullptr, false);
  REQUIRE(seen.is_object());
  return seen;
}

std::size_t motion_events(const RcandProcess& robot) {
  std::size_t moving = 0;
  const json status = drive_status(robot);  // kept: a range-for over a temporary's member would dangle
  for (const auto& event : status["timeline"])
    if (event.value("left", 0.0) != 0.0 || event.value("right", 0.0) != 0.0) ++moving;
  return moving;
}

json latched_sim(bool open_mode) {
  auto config = sim_config();
  config["safety"]["estop_on_startup"] = true;
  if (open_mode) config["runtime"]["auth"] = {{"mode", "open"}};
  return config;
}

void require_browser() {
  for (const char* tool : {"/usr/bin/chromium", "/usr/bin/node"})
    REQUIRE_MESSAGE(fs::exists(tool), tool << " is missing: run packaging/install-deps.sh");
}

}  // namespace

TEST_CASE("origins, auth mode open: another origin's page neither clears, nor drives, nor watches; the robot's own does") {
  require_browser();
  RcandProcess robot(latched_sim(true));
  const std::string own = "http://127.0.0.1:" + std::to_string(robot.port());

  const json hostile = probe("hostile", robot, own);
  INFO(hostile.dump(), "\n", robot.stderr_text());
  CHECK(hostile["ws"] == "refused");  // was "open", with frames: the page read the robot's telemetry
  CHECK(hostile["frames"] == 0);
  CHECK(robot.json("GET", "/api/estop")["estopped"] == true);  // was false: the page cleared the latch
  CHECK(motion_events(robot) == 0);                            // and then drove
  const std::string log = robot.stderr_text();
  CHECK(log.find("POST /api/estop/clear from 127.0.0.1") != std::string::npos);
  CHECK(log.find("POST /api/action from 127.0.0.1") != std::string::npos);
  CHECK(log.find("GET /ws/telemetry from 127.0.0.1") != std::string::npos);
  CHECK(count_of(log, "(another origin than this robot's)") >= 3);

  // DNS rebinding: evil.test resolves to the robot, so its page is same-origin with it by host and port.
  const std::string rebound = "http://evil.test:" + std::to_string(robot.port());
  const json rebinding = probe(rebound + "/health", robot, rebound);
  INFO(rebinding.dump());
  CHECK(rebinding["read"] == 403);  // the page can read these answers: they are its own origin's
  CHECK(rebinding["clear"] == 403);
  CHECK(rebinding["move"] == 403);
  CHECK(rebinding["ws"] == "refused");
  CHECK(robot.json("GET", "/api/estop")["estopped"] == true);
  CHECK(motion_events(robot) == 0);
  // Refusal lines are rate-limited per address (5 a second, Api::kRefusalLogLines) and the hostile probe's three may
  // share a window with these: at least two of the rebinding page's are logged.
  CHECK(count_of(robot.stderr_text(), "'evil.test' is not a name of this robot") >= 2);

  // The robot's own page (the dashboard's origin) is unaffected: it clears, drives and watches.
  const json mine = probe(own + "/health", robot, own);
  INFO(mine.dump());
  CHECK(mine["read"] == 200);
  CHECK(mine["clear"] == 200);
  CHECK(mine["move"] == 200);
  CHECK(mine["ws"] == "open");
  CHECK(mine["frames"] == 2);
  CHECK(robot.json("GET", "/api/estop")["estopped"] == false);
  CHECK(motion_events(robot) > 0);
}

TEST_CASE("origins, tokens mode: a page of another origin that knows a token is refused too; the robot's own page is not") {
  require_browser();
  RcandProcess robot(latched_sim(false));
  const std::string own = "http://127.0.0.1:" + std::to_string(robot.port());

  const json hostile = probe("hostile", robot, own, "owner-token");
  INFO(hostile.dump(), "\n", robot.stderr_text());
  CHECK(hostile["ws"] == "refused");  // was "open": ?token= is all a WebSocket needs, and no browser blocks it
  CHECK(hostile["frames"] == 0);
  CHECK(robot.json("GET", "/api/estop", "guest-token")["estopped"] == true);
  CHECK(motion_events(robot) == 0);
  // Its POSTs carry no credential (no preflight allows one), but they meet the origin rule first: 403, not 401.
  CHECK(count_of(robot.stderr_text(), "(another origin than this robot's)") >= 3);

  const json mine = probe(own + "/health", robot, own, "owner-token");
  INFO(mine.dump());
  CHECK(mine["clear"] == 200);
  CHECK(mine["move"] == 200);
  CHECK(mine["ws"] == "open");
  CHECK(robot.json("GET", "/api/estop", "guest-token")["estopped"] == false);
  CHECK(motion_events(robot) > 0);
}
