// Configs written for other runtimes and RCAN versions (docs/protocol.md §10.3): what rcand supplies, reads as its own
// or ignores, each with a warning; what stays an error; and --strict, which refuses every warning.
#include "libs/config/config_defaults.hpp"
#include "config_test_support.hpp"
#include "libs/config/driver_protocols.hpp"

#include <doctest/doctest.h>

#include <algorithm>

using namespace config_test;
using rcand::config::ConfigDiagnostic;
using rcand::config::LoadOptions;
using rcand::config::model_slug;
using rcand::config::parse_robot_config;

namespace {

bool has(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

// minimal_lines() without manufacturer and model (lines 5 and 6), then `more`.
std::string without_maker(const std::vector<std::string>& more = {}) {
  auto lines = minimal_lines();
  lines.resize(4);
  lines.insert(lines.end(), more.begin(), more.end());
  return join(lines);
}

std::vector<ConfigDiagnostic> strict_errors(const std::string& yaml) {
  try {
    parse_robot_config(yaml, "test.rcan.yaml", "/srv/robot", LoadOptions{.strict = true});
  } catch (const rcand::config::ConfigError& e) {
    return e.diagnostics();
  }
  FAIL("--strict accepted:\n" << yaml);
  return {};
}

}  // namespace

TEST_CASE("model_slug: lower case, one '-' per run of anything else, never empty") {
  CHECK(model_slug("Castor_RC_Car") == "castor-rc-car");
  CHECK(model_slug("  OAK-4  Pro Robot!") == "oak-4-pro-robot");
  CHECK(model_slug("sim-rover") == "sim-rover");
  CHECK(model_slug("___") == "robot");
  CHECK(model_slug("Ünïcode bot") == "n-code-bot");
}

TEST_CASE("metadata.manufacturer and model left out: defaulted, one warning each at the metadata block") {
  const auto loaded = parse_ok(without_maker());
  CHECK(loaded.config.manufacturer == "unknown");
  CHECK(loaded.config.model == "rover-1");  // from robot_name
  REQUIRE(loaded.warnings.size() == 2);
  CHECK(loaded.warnings[0].format() ==
        "test.rcan.yaml:2:1: warning: metadata.model: not set: the model is \"rover-1\", from metadata.robot_name (it "
        "names the robot in its RURI and in discovery); set metadata.model to name it");
  CHECK(loaded.warnings[1].key_path == "metadata.manufacturer");
  CHECK(has(loaded.warnings[1].message, "the manufacturer is \"unknown\""));
  // Given, they are used as written and nothing is said.
  CHECK(parse_ok(join(minimal_lines())).warnings.empty());
}

TEST_CASE("drivers without an id are named <protocol><index>, unique beside the ids written") {
  auto lines = minimal_lines();
  for (const char* line : {
           "drivers:",                 // 7
           "  - protocol: dynamixel",  // 8  -> dynamixel0
           "  - {id: dynamixel1, protocol: sim_arm}",
           "  - protocol: dynamixel",  // 10 -> dynamixel1 is taken: dynamixel2
           "  - protocol: pca9685",    // 11 -> pca9685_0 (the protocol ends in a digit)
           "  - {id: wheels, protocol: gpio}",
       })
    lines.emplace_back(line);
  const auto loaded = parse_ok(join(lines));
  const auto& drivers = loaded.config.drivers;
  REQUIRE(drivers.size() == 5);
  CHECK(drivers[0].id == "dynamixel0");
  CHECK(drivers[1].id == "dynamixel1");
  CHECK(drivers[2].id == "dynamixel2");
  CHECK(drivers[3].id == "pca9685_0");
  CHECK(drivers[4].id == "wheels");
  CHECK(drivers[0].settings["id"] == "dynamixel0");  // the plugin sees the id it runs under
  REQUIRE(loaded.warnings.size() == 3);
  CHECK(loaded.warnings[0].key_path == "drivers[0]");
  CHECK(loaded.warnings[0].mark.line == 8);
  CHECK(has(loaded.warnings[0].message, "no 'id': this driver is \"dynamixel0\""));
  CHECK(loaded.warnings[2].mark.line == 11);
  // Ids written twice are still an error.
  auto twice = minimal_lines();
  twice.insert(twice.end(), {"drivers:", "  - {id: a, protocol: sim}", "  - {id: a, protocol: sim}"});
  CHECK(has(errors_only(parse_errors(join(twice))).at(0).message, "duplicate value \"a\""));
}

TEST_CASE("other runtimes' protocol names for the same hardware are read as rcand's, with a warning") {
  auto lines = minimal_lines();
  lines.insert(lines.end(), {"drivers:", "  - {id: wheels, protocol: L298N}", "  - protocol: mock"});
  const auto loaded = parse_ok(join(lines));
  CHECK(loaded.config.drivers[0].protocol == "gpio");
  CHECK(loaded.config.drivers[0].settings["protocol"] == "gpio");
  CHECK(loaded.config.drivers[1].protocol == "sim_diff_drive");
  CHECK(loaded.config.drivers[1].id == "sim_diff_drive0");  // named after the protocol it runs as
  REQUIRE(loaded.warnings.size() == 3);
  CHECK(loaded.warnings[0].format() ==
        "test.rcan.yaml:8:18: warning: drivers[0].protocol: \"L298N\" is read as rcand's protocol \"gpio\" (GPIO "
        "H-bridges (L298N)); write \"gpio\" to say so (a plugin that provides \"L298N\" itself serves it instead)");
  CHECK(loaded.config.drivers[0].written_protocol == "L298N");
  CHECK(loaded.config.drivers[1].written_protocol == "mock");
  // Names rcand knows for hardware it has no plugin for stay as written: --check-config says what would serve them.
  auto other = minimal_lines();
  other.insert(other.end(), {"drivers:", "  - {id: car, protocol: pca9685_rc}"});
  CHECK(parse_ok(join(other)).config.drivers[0].protocol == "pca9685_rc");
}

TEST_CASE("--check-config's advice for a protocol no installed plugin serves") {
  using rcand::config::with_protocol_advice;
  const ConfigDiagnostic unserved{ConfigDiagnostic::Severity::Error,
                                  {"r.rcan.yaml", 9, 15},
                                  "drivers[1].protocol",
                                  "no installed plugin provides driver protocol 'x'"};
  const auto roboclaw = with_protocol_advice(unserved, {"gpio", "roboclaw"});
  CHECK(has(roboclaw.message,
            "(a RoboClaw motor controller (packet serial): rcand has no plugin for it; a driver plugin "
            "that provides it is needed: build one with the SDK (sdk/README.md)"));
  CHECK(has(with_protocol_advice(unserved, {"gpio", "pca9685"}).message,
            "(plugin org.rcand.pca9685 in package rcand-plugins-hw provides it)"));
  CHECK(has(with_protocol_advice(unserved, {"gpio", "acme_lidar"}).message, "a driver plugin that provides it is needed"));
  // (A camera written as a driver never gets here: it is read as the camera block, libs/config/foreign_shapes.hpp.)
  CHECK(has(with_protocol_advice(unserved, {"gpio", "gpio_hcsr04"}).message, "an HC-SR04 ultrasonic ranger, a sensor"));
  // A misspelling keeps only its did-you-mean; other diagnostics and bad indices are left alone.
  auto typo = unserved;
  typo.message += "; did you mean 'gpio'?";
  CHECK(with_protocol_advice(typo, {"gpio", "gpoi"}).message == typo.message);
  CHECK(with_protocol_advice(unserved, {"gpio"}).message == unserved.message);
  auto other = unserved;
  other.key_path = "rcan_protocol.capabilities";
  CHECK(with_protocol_advice(other, {"gpio", "roboclaw"}).message == unserved.message);
}

TEST_CASE("nav listed without the §10.2 physics: dropped with a warning naming the field, refused with --strict") {
  auto lines = minimal_lines();
  lines.insert(lines.end(),
               {"physics:", "  wheel_circumference_m: 0.2", "rcan_protocol:", "  capabilities: [status, nav, teleop]"});
  const auto loaded = parse_ok(join(lines));
  REQUIRE(loaded.config.capabilities.has_value());
  CHECK(*loaded.config.capabilities == std::vector<std::string>{"status", "teleop"});
  REQUIRE(loaded.warnings.size() == 1);
  const auto& w = loaded.warnings[0];
  CHECK(w.key_path == "rcan_protocol.capabilities[1]");
  CHECK(w.mark.line == 10);
  CHECK(has(w.message, "'nav' is listed, but physics.turn_time_per_deg_s is missing"));
  CHECK(has(w.message, "the robot starts without nav"));
  const auto refused = strict_errors(join(lines));
  REQUIRE(refused.size() == 1);
  CHECK(refused[0].severity == ConfigDiagnostic::Severity::Error);
  CHECK(has(refused[0].format(), "test.rcan.yaml:10:"));
  CHECK(has(refused[0].format(), "error: rcan_protocol.capabilities[1]: 'nav' is listed, but physics.turn_time_per_deg_s"));
  CHECK(has(refused[0].message, "[refused: --strict]"));
  // With both fields nav stays, and auto-detection (no list) is left to the registry.
  lines.insert(lines.begin() + 8, "  turn_time_per_deg_s: 0.008");
  CHECK(*parse_ok(join(lines)).config.capabilities == std::vector<std::string>{"status", "nav", "teleop"});
}

TEST_CASE("rcan_version: 1.x silently, another major with one warning, no version at all an error") {
  for (const char* version : {"\"1.3\"", "\"1.0.0-alpha\"", "\"1\"", "\"v1.3.0\"", "\"1.4\""}) {
    CAPTURE(version);
    auto lines = minimal_lines();
    lines[0] = std::string("rcan_version: ") + version;
    CHECK(parse_ok(join(lines)).warnings.empty());
  }
  auto lines = minimal_lines();
  lines[0] = "rcan_version: \"2.1\"";
  const auto newer = parse_ok(join(lines));
  REQUIRE(newer.warnings.size() == 1);
  CHECK(newer.warnings[0].format() ==
        "test.rcan.yaml:1:1: warning: rcan_version: the file is written for RCAN 2.1; rcand implements RCAN 1.3 "
        "(1.3.0) and reads it as 1.3: the keys 1.3 defines are used as 1.3 defines them, the others are ignored");
  lines[0] = "rcan_version: \"latest\"";
  const auto bad = parse_errors(join(lines));
  REQUIRE(bad.size() == 1);
  CHECK(bad[0].key_path == "rcan_version");
  CHECK(has(bad[0].message, "expected an RCAN version such as \"1.3\""));
}

TEST_CASE("keys of newer RCAN versions and other runtimes: one warning lists them all, in file order") {
  const std::string yaml = R"(rcan_version: "3.0"
authority_handler_enabled: true
metadata:
  robot_name: bob
  robot_uuid: 0badc0de-0000-4000-8000-000000000000
  manufacturer: acme
  model: r1
  author: someone
  tags: [mobile]
  rrn: RRN-000000000001
port: 8000
capabilities: [status]
safety:
  watchdog: {timeout_s: 10}
  max_linear_speed_mps: 0.2
  local_safety_wins: true
brain: {provider: google}
notes: {setup: flash it}
)";
  const auto loaded = parse_ok(yaml);
  REQUIRE(loaded.warnings.size() == 2);  // the version, and the one list
  CHECK(loaded.warnings[0].key_path == "rcan_version");
  const auto& list = loaded.warnings[1];
  CHECK(list.mark.line == 2);
  CHECK(list.key_path.empty());
  CHECK(list.message ==
        "11 keys of other RCAN versions or runtimes, not implemented by rcand (RCAN 1.3), ignored: "
        "authority_handler_enabled (line 2; newer RCAN), metadata.author (line 8; another runtime's), metadata.tags "
        "(line 9; another runtime's), metadata.rrn (line 10; newer RCAN, rcand reads metadata.ruri), port (line 11; "
        "newer RCAN, rcand reads rcan_protocol.port), capabilities (line 12; newer RCAN, rcand reads "
        "rcan_protocol.capabilities), safety.watchdog (line 14; newer RCAN, rcand reads safety.watchdog_ms), "
        "safety.max_linear_speed_mps (line 15; another runtime's, rcand reads safety.max_linear_speed), "
        "safety.local_safety_wins (line 16; newer RCAN), brain (line 17; newer RCAN, rcand reads agent), notes (line "
        "18; another runtime's)");
  // The same file with --strict: each warning an error.
  CHECK(strict_errors(yaml).size() == 2);
}

TEST_CASE("an unknown key within a small edit distance of a known one stays an error with the suggestion") {
  struct Case {
    const char* line;
    const char* expected;
  };
  for (const Case& c : {
           Case{"rcan_protocl: {port: 8000}", "unknown key 'rcan_protocl'; did you mean 'rcan_protocol'?"},
           Case{"phyiscs: {dof: 2}", "unknown key 'phyiscs'; did you mean 'physics'?"},
           Case{"safety: {watchdog_sm: 300}", "unknown key 'watchdog_sm'; did you mean 'watchdog_ms'?"},
           Case{"safety: {estop_on_start: true}", "unknown key 'estop_on_start'; did you mean 'estop_on_startup'?"},
           Case{"agent: {provdier: grammar}", "unknown key 'provdier'; did you mean 'provider'?"},
       }) {
    CAPTURE(c.line);
    auto lines = minimal_lines();
    lines.emplace_back(c.line);
    const auto errors = errors_only(parse_errors(join(lines)));
    REQUIRE(errors.size() == 1);
    CHECK(has(errors[0].message, c.expected));
  }
}

TEST_CASE("--strict: a file with no warning passes, any warning is refused at its own position") {
  CHECK(strict_errors(without_maker()).size() == 2);
  auto lines = minimal_lines();
  CHECK_NOTHROW(parse_robot_config(join(lines), "test.rcan.yaml", "/srv/robot", LoadOptions{.strict = true}));
  lines.emplace_back("audio: {tts_enabled: true}");
  const auto refused = strict_errors(join(lines));
  REQUIRE(refused.size() == 1);
  CHECK(refused[0].mark.line == 7);
  CHECK(has(refused[0].format(), "error: 1 key of other RCAN versions or runtimes"));
  // The process-wide default is what rcand --strict sets; an explicit option overrides it.
  rcand::config::set_default_load_options(LoadOptions{.strict = true});
  const bool strict_by_default = rcand::config::default_load_options().strict;
  CHECK_THROWS_AS(parse_robot_config(join(lines), "test.rcan.yaml", "/srv/robot"), rcand::config::ConfigError);
  rcand::config::set_default_load_options(LoadOptions{});
  CHECK(strict_by_default);
  CHECK_FALSE(rcand::config::default_load_options().strict);
  CHECK(parse_ok(join(lines)).warnings.size() == 1);
}

TEST_CASE("a robot_uuid that is no device id: identity from the install, with a warning") {
  auto lines = minimal_lines();
  lines[3] = "  robot_uuid: bob-001";
  if (!std::filesystem::exists("/etc/machine-id")) {
    MESSAGE("skipped: no /etc/machine-id");
    return;
  }
  const auto loaded = parse_ok(join(lines));
  CHECK(loaded.config.robot_uuid != "bob-001");
  CHECK(std::count_if(loaded.config.robot_uuid.begin(), loaded.config.robot_uuid.end(),
                      [](unsigned char c) { return std::isxdigit(c) != 0; }) == 32);
  REQUIRE(loaded.warnings.size() == 1);
  CHECK(loaded.warnings[0].key_path == "metadata.robot_uuid");
  CHECK(has(loaded.warnings[0].message, "derived from /etc/machine-id"));
}
