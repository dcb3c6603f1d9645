// docs/protocol.md §10: config errors stop startup with file:line:column and the key path; --check-config validates only.
#include <doctest/doctest.h>

#include "rcand_process.hpp"

using namespace rcand::test;

namespace {

const char* kValid = R"(rcan_version: "1.3"
metadata:
  robot_name: yaml-rover
  robot_uuid: 0badc0de-0000-4000-8000-000000000000
  manufacturer: acme
  model: r1
physics:
  wheel_circumference_m: 0.21
  turn_time_per_deg_s: 0.008
drivers:
  - id: drive0
    protocol: sim_diff_drive
rcan_protocol:
  capabilities: [status, teleop]
runtime:
  auth:
    mode: open
)";

ProcessResult check(const std::string& yaml) {
  TempDir dir;
  const auto file = dir.write("robot.rcan.yaml", yaml);
  return run_tool(rcand_binary(), {"--check-config", file.string(), "--plugin-path", plugin_dir().string()});
}

std::string replace(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  REQUIRE(at != std::string::npos);
  return text.replace(at, from.size(), to);
}

}  // namespace

TEST_CASE("--check-config accepts the bundled sim config and a minimal one") {
  auto bundled = run_tool(rcand_binary(), {"--check-config", std::string(RCAND_SOURCE_DIR) + "/config/sim-rover.rcan.yaml",
                                           "--plugin-path", plugin_dir().string()});
  CHECK(bundled.exit_code == 0);
  CHECK(bundled.out.find("OK") != std::string::npos);
  for (const char* capability : {"teleop", "nav", "vision", "arm", "chat", "com.acme.gripper"})  // the sim robot shows them all
    CHECK_MESSAGE(bundled.out.find(capability) != std::string::npos, capability);
  // Every actuating driver's hardware fail-safe, from its manifest (issue 17).
  for (const char* driver :
       {"fail-safe of drive0 (sim_diff_drive): ", "fail-safe of arm0 (sim_arm): ", "fail-safe of gripper0 (acme_gripper_sim): "})
    CHECK_MESSAGE(bundled.out.find(driver) != std::string::npos, driver, bundled.out);
  auto minimal = check(kValid);
  CHECK(minimal.exit_code == 0);
  CHECK(minimal.out.find("status, teleop") != std::string::npos);
}

TEST_CASE("a missing required key stops startup with file:line:column and the key path") {
  auto result = check(replace(kValid, "  robot_name: yaml-rover\n", ""));
  CHECK(result.exit_code == 1);
  CHECK(result.err.find("robot.rcan.yaml:2:") != std::string::npos);
  CHECK(result.err.find("metadata.robot_name") != std::string::npos);
}

TEST_CASE("a wrong type names the key, the position and what was expected") {
  auto result = check(replace(kValid, "wheel_circumference_m: 0.21", "wheel_circumference_m: wide"));
  CHECK(result.exit_code == 1);
  CHECK(result.err.find("robot.rcan.yaml:8:") != std::string::npos);
  CHECK(result.err.find("physics.wheel_circumference_m") != std::string::npos);
  CHECK(result.err.find("number") != std::string::npos);
}

TEST_CASE("a misspelled section is an error with the suggestion; another runtime's key only warns") {
  auto misspelled = check(replace(kValid, "rcan_protocol:", "rcan_protocl:"));
  CHECK(misspelled.exit_code == 1);
  CHECK(misspelled.err.find("error: unknown key 'rcan_protocl'; did you mean 'rcan_protocol'?") != std::string::npos);
  auto foreign = check(replace(kValid, "physics:", "brain_backend_url: http://x\nphysics:"));
  CHECK(foreign.exit_code == 0);
  CHECK(foreign.err.find("warning: unknown key 'brain_backend_url'") != std::string::npos);
}

TEST_CASE("an explicitly listed capability that no installed plugin provides stops startup naming the plugin") {
  // An install with the drive plugins only (as rcand-plugins-core without chat would be).
  TempDir dir;
  const auto plugins = dir.path() / "plugins";
  std::filesystem::create_directories(plugins);
  for (const char* file : {"rcand_teleop.so", "teleop.json", "rcand_sim_drive.so", "sim_drive.json"})
    std::filesystem::copy_file(plugin_dir() / file, plugins / file);
  const auto config = dir.write("robot.rcan.yaml", replace(kValid, "[status, teleop]", "[status, teleop, chat]"));
  auto result = run_tool(rcand_binary(), {"--check-config", config.string(), "--plugin-path", plugins.string()});
  CHECK(result.exit_code == 1);
  CHECK(result.err.find("rcan_protocol.capabilities[2]") != std::string::npos);
  CHECK(result.err.find("org.rcand.chat") != std::string::npos);
  CHECK(result.err.find(":14:") != std::string::npos);
}

TEST_CASE("nav without the §10.2 physics fields is refused") {
  auto yaml = replace(kValid, "  turn_time_per_deg_s: 0.008\n", "");
  auto result = check(replace(yaml, "[status, teleop]", "[status, nav]"));
  CHECK(result.exit_code == 1);
  CHECK(result.err.find("turn_time_per_deg_s") != std::string::npos);
}

TEST_CASE("YAML syntax errors and missing files are reported, and rcand does not start") {
  auto result = check("metadata: [unclosed\n");
  CHECK(result.exit_code == 1);
  CHECK(result.err.find("robot.rcan.yaml:") != std::string::npos);
  auto missing = run_tool(rcand_binary(), {"--config", "/nonexistent/robot.rcan.yaml"});
  CHECK(missing.exit_code == 1);
  CHECK(missing.err.find("/nonexistent/robot.rcan.yaml") != std::string::npos);
}

TEST_CASE("plugin settings are validated against the manifest schema with the config position") {
  auto result = check(replace(kValid, "    protocol: sim_diff_drive\n", "    protocol: sim_diff_drive\n    halt_delay_ms: soon\n"));
  CHECK(result.exit_code == 1);
  CHECK(result.err.find("drivers[0]") != std::string::npos);
  CHECK(result.err.find("halt_delay_ms") != std::string::npos);
  CHECK(result.err.find("robot.rcan.yaml:13:5") != std::string::npos);  // the key's own position
}

TEST_CASE("--check-config fails on a driver or capability the installed plugins cannot serve") {
  auto misspelled = check(replace(kValid, "protocol: sim_diff_drive", "protocol: sim_dif_drive"));
  CHECK(misspelled.exit_code == 1);
  CHECK(misspelled.err.find("drivers[0].protocol: no installed plugin provides driver protocol 'sim_dif_drive'; "
                            "did you mean 'sim_diff_drive'?") != std::string::npos);
  auto missing = check(replace(kValid, "protocol: sim_diff_drive", "protocol: roboclaw"));
  CHECK(missing.exit_code == 1);
  CHECK(missing.err.find("no installed plugin provides driver protocol 'roboclaw'") != std::string::npos);
  // A hardware driver passes without its hardware (nothing is opened) and says what its board does on its own.
  auto hardware = check(replace(kValid, "protocol: sim_diff_drive", "protocol: pca9685_i2c"));
  INFO(hardware.out, hardware.err);
  CHECK(hardware.exit_code == 0);
  CHECK(hardware.out.find("fail-safe of drive0 (pca9685_i2c): ") != std::string::npos);
  // teleop needs a differential_drive actuator: with no driver it could only answer 503.
  auto no_drive = check(replace(kValid, "drivers:\n  - id: drive0\n    protocol: sim_diff_drive\n", "drivers: []\n"));
  CHECK(no_drive.exit_code == 1);
  CHECK(no_drive.err.find("capability teleop requires a differential_drive actuator") != std::string::npos);
}

TEST_CASE("§9.3 from real driver blocks: a dynamixel with kinematics declares arm, a drive declares nav and teleop") {
  std::string yaml = replace(kValid, "rcan_protocol:\n  capabilities: [status, teleop]\n", "");
  yaml = replace(yaml, "  turn_time_per_deg_s: 0.008\n",
                 "  turn_time_per_deg_s: 0.008\n  kinematics:\n    - {joint: shoulder, min_deg: -90, max_deg: 90}\n");
  yaml = replace(yaml, "    protocol: sim_diff_drive\n",
                 "    protocol: sim_diff_drive\n  - id: arm0\n    protocol: dynamixel_v2\n    port: /dev/ttyUSB0\n"
                 "    servos: [{id: 1, joint: shoulder}]\n");
  const auto result = check(yaml);
  INFO(result.out, result.err);
  CHECK(result.exit_code == 0);
  CHECK(result.out.find("capabilities: status, nav, teleop, arm") != std::string::npos);
  CHECK(result.out.find("fail-safe of arm0 (dynamixel_v2): the servos' Bus Watchdog") != std::string::npos);
}

TEST_CASE("--check-config starts no driver and writes no file") {
  TempDir dir;
  const std::string yaml = replace(kValid, "runtime:\n", "runtime:\n  state_dir: state\n  audit_file: audit.jsonl\n");
  const auto file = dir.write("robot.rcan.yaml", yaml);
  const auto result = run_tool(rcand_binary(), {"--check-config", file.string(), "--plugin-path", plugin_dir().string()});
  INFO(result.err);
  CHECK(result.exit_code == 0);
  CHECK(result.out.find("OK") != std::string::npos);
  CHECK(result.err.find("started") == std::string::npos);  // no "driver drive0 ... started"
  CHECK_FALSE(std::filesystem::exists(dir.path() / "state"));
  CHECK_FALSE(std::filesystem::exists(dir.path() / "audit.jsonl"));
  CHECK(std::distance(std::filesystem::directory_iterator(dir.path()), std::filesystem::directory_iterator()) == 1);
}

TEST_CASE("--check-config --as-user checks that the service's user can open every path the config names") {
  TempDir dir;  // mkdtemp: 0700, so only its owner (and root) can enter it
  const auto file = dir.write("robot.rcan.yaml", replace(kValid, "    protocol: sim_diff_drive\n",
                                                         "    protocol: sim_diff_drive\n    port: /dev/ttyRCAND-TEST0\n"));
  const std::vector<std::string> base{"--check-config", file.string(), "--plugin-path", plugin_dir().string()};
  auto as = [&](const std::string& user) {
    auto args = base;
    args.insert(args.end(), {"--as-user", user});
    return run_tool(rcand_binary(), args);
  };
  const auto nobody = as("nobody");
  INFO(nobody.err);
  CHECK(nobody.exit_code == 1);
  CHECK(nobody.err.find("rcand: --as-user nobody: " + dir.path().string() + ": not searchable by nobody") != std::string::npos);
  CHECK(nobody.err.find("/dev/ttyRCAND-TEST0: does not exist") != std::string::npos);
  CHECK(as("no-such-user-rcand").exit_code == 2);
}

TEST_CASE("rcand --version and bad arguments") {
  auto version = run_tool(rcand_binary(), {"--version"});
  CHECK(version.exit_code == 0);
  CHECK(version.out.find("RCAN 1.3.0") != std::string::npos);
  CHECK(run_tool(rcand_binary(), {"--bogus"}).exit_code == 2);
  CHECK(run_tool(rcand_binary(), {"--port", "99999"}).exit_code == 2);
}
