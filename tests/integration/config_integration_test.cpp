// docs/protocol.md §10: config errors stop startup with file:line:column and the key path; --check-config validates only.
#include <doctest/doctest.h>

#include "libs/config/config_schema.hpp"
#include "rcand_process.hpp"

#include <algorithm>
#include <fstream>
#include <optional>
#include <set>
#include <string_view>

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
  CHECK(foreign.err.find("warning: 1 key of other RCAN versions or runtimes, not implemented by rcand (RCAN 1.3), "
                         "ignored: brain_backend_url (line 7)") != std::string::npos);
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

TEST_CASE("nav without the §10.2 physics fields: the robot starts without nav (§9.5), --strict refuses naming the field") {
  const auto yaml = replace(replace(kValid, "  turn_time_per_deg_s: 0.008\n", ""), "[status, teleop]", "[status, nav, teleop]");
  auto result = check(yaml);
  INFO(result.err);
  CHECK(result.exit_code == 0);
  CHECK(result.out.find("OK (capabilities: status, teleop)") != std::string::npos);
  CHECK(result.err.find("robot.rcan.yaml:13:26: warning: rcan_protocol.capabilities[1]: 'nav' is listed, but "
                        "physics.turn_time_per_deg_s is missing") != std::string::npos);
  TempDir dir;
  const auto file = dir.write("robot.rcan.yaml", yaml);
  auto strict = run_tool(rcand_binary(), {"--check-config", file.string(), "--plugin-path", plugin_dir().string(), "--strict"});
  CHECK(strict.exit_code == 1);
  CHECK(strict.err.find("robot.rcan.yaml:13:26: error: rcan_protocol.capabilities[1]: 'nav' is listed, but "
                        "physics.turn_time_per_deg_s is missing") != std::string::npos);
  CHECK(strict.err.find("[refused: --strict]") != std::string::npos);
  auto refused = run_tool(rcand_binary(), {"--config", file.string(), "--plugin-path", plugin_dir().string(), "--strict"});
  CHECK(refused.exit_code == 1);
  CHECK(refused.err.find("rcand: configuration invalid; not started") != std::string::npos);
  // Served: the robot advertises the rest of the list, logs the discrepancy, and nav's route is not there (§9.1).
  const RcandProcess robot(nlohmann::json{
      {"rcan_version", "1.3"},
      {"metadata", {{"robot_name", "half"}, {"robot_uuid", "0badc0de"}, {"manufacturer", "acme"}, {"model", "r1"}}},
      {"physics", {{"wheel_circumference_m", 0.21}}},
      {"drivers", {{{"id", "drive0"}, {"protocol", "sim_diff_drive"}}}},
      {"rcan_protocol", {{"capabilities", {"status", "nav", "teleop"}}}},
      {"runtime", {{"auth", {{"mode", "open"}}}}}});
  CHECK(robot.json("GET", "/api/discovery")["capabilities"] == nlohmann::json{"status", "teleop"});
  int status = 0;
  const auto nav = robot.json("POST", "/api/nav/waypoint", "", R"({"distance_m":1,"heading_deg":0})", &status);
  CHECK(status == 404);
  CHECK(nav["code"] == "CAPABILITY_NOT_FOUND");
  CHECK(robot.stderr_text().find("warning: rcan_protocol.capabilities[1]: 'nav' is listed") != std::string::npos);
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
  auto result =
      check(replace(kValid, "    protocol: sim_diff_drive\n", "    protocol: sim_diff_drive\n    halt_delay_ms: soon\n"));
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
  auto hardware = check(replace(kValid, "protocol: sim_diff_drive",
                                "protocol: pca9685_i2c\n    channels:\n      left: {esc: 0}\n      right: {esc: 1}"));
  INFO(hardware.out, hardware.err);
  CHECK(hardware.exit_code == 0);
  CHECK(hardware.out.find("fail-safe of drive0 (pca9685_i2c): ") != std::string::npos);
  // teleop needs a differential_drive actuator: with no driver it could only answer 503.
  auto no_drive = check(replace(kValid, "drivers:\n  - id: drive0\n    protocol: sim_diff_drive\n", "drivers: []\n"));
  CHECK(no_drive.exit_code == 1);
  CHECK(no_drive.err.find("capability teleop requires a differential_drive actuator") != std::string::npos);
}

TEST_CASE("a protocol other runtimes write is rcand's alias only while no installed plugin provides that name") {
  TempDir dir;
  const auto file = dir.write("robot.rcan.yaml", replace(kValid, "protocol: sim_diff_drive", "protocol: l298n"));
  // rcand's own plugins only: read as gpio, so the gpio plugin's settings apply (and its pins are missing).
  const auto aliased = run_tool(rcand_binary(), {"--check-config", file.string(), "--plugin-path", plugin_dir().string()});
  CHECK(aliased.err.find("\"l298n\" is read as rcand's protocol \"gpio\"") != std::string::npos);
  CHECK(aliased.err.find("served by plugin") == std::string::npos);
  // A vendor plugin that provides "l298n" serves the driver as written.
  const auto vendor = run_tool(rcand_binary(), {"--check-config", file.string(), "--plugin-path", plugin_dir().string(),
                                                "--plugin-path", (test_plugin_dir() / "vendor_l298n").string()});
  INFO(vendor.out, vendor.err);
  CHECK(vendor.exit_code == 0);
  CHECK(vendor.err.find("driver drive0: protocol 'l298n' is served by plugin com.acme.l298n, which provides it") !=
        std::string::npos);
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

// tests/configs/: configs written in the style of other RCAN runtimes and tools, each with its expected outcome in
// its header (tests/configs/README.md), run through the real `rcand --check-config`, with and without --strict.
namespace {

struct CorpusEntry {
  std::filesystem::path file;
  std::string outcome;  // starts | warns | refuses
  std::vector<std::string> expect, strict_expect;
};

CorpusEntry read_corpus_entry(const std::filesystem::path& file) {
  CorpusEntry entry{file, {}, {}, {}};
  std::ifstream in(file);
  for (std::string line; std::getline(in, line) && line.starts_with("#");) {
    const auto field = [&](std::string_view prefix) -> std::optional<std::string> {
      if (!line.starts_with(prefix)) return std::nullopt;
      return line.substr(prefix.size());
    };
    if (auto value = field("# outcome: ")) entry.outcome = *value;
    if (auto value = field("# expect: ")) entry.expect.push_back(*value);
    if (auto value = field("# strict-expect: ")) entry.strict_expect.push_back(*value);
  }
  return entry;
}

std::vector<CorpusEntry> corpus() {
  std::vector<CorpusEntry> entries;
  for (const auto& item :
       std::filesystem::recursive_directory_iterator(std::filesystem::path(RCAND_SOURCE_DIR) / "tests" / "configs"))
    if (item.path().string().ends_with(".rcan.yaml") && item.path().string().find("/opencastor/") == std::string::npos)
      entries.push_back(read_corpus_entry(item.path()));  // opencastor/: the reference runtime's presets, as they are
  std::sort(entries.begin(), entries.end(), [](const auto& a, const auto& b) { return a.file < b.file; });
  return entries;
}

ProcessResult check_corpus_file(const CorpusEntry& entry, bool strict) {
  // Messages name the file by this absolute path, which ends in the name the headers' expectations start with.
  std::vector<std::string> args{"--check-config", entry.file.string(), "--plugin-path", plugin_dir().string()};
  if (strict) args.emplace_back("--strict");
  return run_tool(rcand_binary(), args);
}

}  // namespace

TEST_CASE("tests/configs: every config gives the outcome its header states, with and without --strict") {
  const auto entries = corpus();
  CHECK(entries.size() >= 22);
  for (const auto& entry : entries) {
    const std::string name = entry.file.filename().string();
    INFO(name);
    REQUIRE_MESSAGE((entry.outcome == "starts" || entry.outcome == "warns" || entry.outcome == "refuses"),
                    "no '# outcome:' line");
    CHECK_MESSAGE(!entry.expect.empty(), "no '# expect:' line");
    const auto plain = check_corpus_file(entry, false);
    const std::string output = plain.out + plain.err;
    INFO(output);
    CHECK(plain.exit_code == (entry.outcome == "refuses" ? 1 : 0));
    if (entry.outcome != "refuses")  // a refused file may carry warnings as well
      CHECK((output.find(": warning: ") != std::string::npos) == (entry.outcome == "warns"));
    if (entry.outcome != "refuses") CHECK(plain.out.find("/" + name + ": OK (capabilities: ") != std::string::npos);
    for (const auto& text : entry.expect) CHECK_MESSAGE(output.find(text) != std::string::npos, "expected: " << text);

    const auto strict = check_corpus_file(entry, true);
    const std::string strict_output = strict.out + strict.err;
    INFO(strict_output);
    CHECK(strict.exit_code == (entry.outcome == "starts" ? 0 : 1));
    if (entry.outcome == "warns") {
      CHECK(strict_output.find("[refused: --strict]") != std::string::npos);
      CHECK(strict_output.find(": warning: ") == std::string::npos);  // every warning became an error
    }
    for (const auto& text : entry.strict_expect)
      CHECK_MESSAGE(strict_output.find(text) != std::string::npos, "expected with --strict: " << text);
  }
}

TEST_CASE("tests/configs covers every driver protocol of rcand's plugins and every block rcand reads") {
  std::set<std::string> protocols, blocks;  // as written in configs that load
  for (const auto& entry : corpus()) {
    if (entry.outcome == "refuses") continue;
    const auto doc = rcand::config::load_robot_config(entry.file).config.doc;
    for (const auto& [key, value] : doc.items()) blocks.insert(key);
    for (const auto& driver : doc.value("drivers", nlohmann::json::array())) protocols.insert(driver.value("protocol", ""));
  }
  for (const auto& item : std::filesystem::directory_iterator(plugin_dir())) {
    if (item.path().extension() != ".json") continue;
    std::ifstream in(item.path());
    const auto manifest = nlohmann::json::parse(in);
    for (const auto& provided : manifest.value("provides", nlohmann::json::array()))
      if (provided.value("kind", "") == "driver")
        CHECK_MESSAGE(protocols.contains(provided.value("name", "")),
                      "no config that loads uses driver protocol " << provided.value("name", ""));
  }
  for (const auto* row : rcand::config::detail::config_schema()) {
    const std::string path(row->path);
    if (path.find('.') == std::string::npos && path.find('[') == std::string::npos)
      CHECK_MESSAGE(blocks.contains(path), "no config that loads has the block " << path);
  }
}
