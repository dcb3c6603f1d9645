// The dashboard in Debian's headless Chromium against a real rcand: tests/dashboard/drive.mjs (playwright-core, pinned
// in tests/dashboard/package-lock.json) logs in, drives with the pad, presses STOP, clears, stops a second real rcand
// from the swarm table, and drops the link while holding the pad; each step's screenshot lands in
// <build>/tests/dashboard-screenshots/. Chromium, Node.js and npm
// come from packaging/install-deps.sh; playwright-core from the npm registry (`npm ci`, once per lock file).
#include <doctest/doctest.h>

#include <filesystem>

#include "node_dir.hpp"
#include "rcand_process.hpp"
#include "swarm_lab.hpp"

namespace fs = std::filesystem;
using rcand::test::run_tool;

TEST_CASE("the dashboard in a real browser: log in, drive, stop, clear, stop one swarm node, a lost link stops the motors") {
  for (const char* tool : {"/usr/bin/chromium", "/usr/bin/node"})
    REQUIRE_MESSAGE(fs::exists(tool), tool << " is missing: run packaging/install-deps.sh");
  const fs::path node_dir = rcand::test::prepared_node_dir();

  // A second robot, the only node of the first one's swarm file.
  rcand::test::RcandProcess bravo(rcand::test::swarm_robot_config("bravo"));
  rcand::test::TempDir dir;
  const auto swarm_file = dir.write("swarm.yaml", rcand::test::swarm_yaml({{"bravo", "127.0.0.1", bravo.port()}}));
  auto config = rcand::test::swarm_robot_config("alpha", swarm_file);
  config["rcan_protocol"]["capabilities"].push_back("nav");
  rcand::test::RcandProcess rcand(config);
  const std::string base = "http://127.0.0.1:" + std::to_string(rcand.port());
  const std::string bravo_url = "http://127.0.0.1:" + std::to_string(bravo.port());
  const fs::path shots = fs::path(RCAND_BINARY_DIR) / "tests/dashboard-screenshots";
  const auto run =
      run_tool("/usr/bin/node", {(node_dir / "drive.mjs").string(), base, "owner-token", shots.string(), "bravo", bravo_url});
  INFO("drive.mjs:\n", run.out, run.err);
  CHECK(run.exit_code == 0);
  CHECK(run.out.find("ok - link lost while holding: the motors stop") != std::string::npos);
  CHECK(run.out.find("ok - per-node stop latches that node only") != std::string::npos);
  CHECK(bravo.json("GET", "/api/estop", "guest-token")["estopped"] == true);  // seen from here too
  CHECK(rcand.json("GET", "/api/estop", "guest-token")["estopped"] == false);
  for (const char* shot :
       {"1-login.png", "2-dashboard.png", "3-driving.png", "4-estopped.png", "5-link-lost.png", "6-phone.png", "7-swarm.png"})
    CHECK_MESSAGE(fs::is_regular_file(shots / shot), shot);
}

// Issue 29 item 4: a robot whose only arm driver (a Dynamixel on a port that does not exist) and one of whose two
// drives failed. tests/dashboard/state.mjs checks the colours (pixels of its screenshots), the reasons in the rows,
// the latch banner on a desktop and on a scrolled 390x844 phone, and that clear shows only while latched, for owners.
TEST_CASE("the dashboard makes the robot's state impossible to miss: colours, reasons, the latch banner, clear") {
  for (const char* tool : {"/usr/bin/chromium", "/usr/bin/node"})
    REQUIRE_MESSAGE(fs::exists(tool), tool << " is missing: run packaging/install-deps.sh");
  const fs::path node_dir = rcand::test::prepared_node_dir();
  const std::string missing_port = "/dev/rcand-test-no-such-u2d2";
  auto config = rcand::test::swarm_robot_config("alpha");
  config["physics"]["kinematics"] = nlohmann::json::array(
      {{{"joint", "shoulder"}, {"min_deg", -90}, {"max_deg", 90}}, {{"joint", "elbow"}, {"min_deg", 0}, {"max_deg", 135}}});
  config["drivers"].push_back(
      {{"id", "arm0"},
       {"protocol", "dynamixel"},
       {"port", missing_port},
       {"servos", nlohmann::json::array({{{"id", 1}, {"joint", "shoulder"}}, {{"id", 2}, {"joint", "elbow"}}})}});
  config["drivers"].push_back({{"id", "drive1"}, {"protocol", "org.rcand.test.faulty_drive"}, {"hook", "factory"}});
  config["rcan_protocol"]["capabilities"].push_back("arm");
  rcand::test::RcandProcess rcand(config, {rcand::test::plugin_dir(), rcand::test::test_plugin_dir() / "faults"});
  const std::string base = "http://127.0.0.1:" + std::to_string(rcand.port());
  const fs::path shots = fs::path(RCAND_BINARY_DIR) / "tests/dashboard-screenshots";
  const auto run = run_tool(
      "/usr/bin/node", {(node_dir / "state.mjs").string(), base, "owner-token", "guest-token", shots.string(), missing_port});
  INFO("state.mjs:\n", run.out, run.err);
  CHECK(run.exit_code == 0);
  for (const char* step :
       {"ok - the error badge is red (pixels)", "ok - the banner is red across the page (pixels)",
        "ok - the banner stays at the top of a scrolled phone", "ok - no clear button for a guest while latched",
        "ok - the failed driver shows its reason, device and hint in its row", "ok - degraded is amber"})
    CHECK_MESSAGE(run.out.find(step) != std::string::npos, step);
  CHECK(rcand.json("GET", "/api/estop", "guest-token")["estopped"] == false);  // the owner's phone cleared it
  for (const char* shot : {"state-1-error.png", "state-2-latched-desktop.png", "state-4-latched-phone-scrolled.png"})
    CHECK_MESSAGE(fs::is_regular_file(shots / shot), shot);
}
