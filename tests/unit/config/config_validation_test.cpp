// Bad files: every problem reported at once, with file:line:column, the key path, what was expected and found.
#include "config_test_support.hpp"
#include "libs/rcan/loopback.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <tuple>

using namespace config_test;
using rcand::config::ConfigDiagnostic;
using rcand::config::ConfigError;
using rcand::config::parse_robot_config;

namespace {

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

// minimal_lines() plus a driver and a token, so every required key has a line to remove.
std::vector<std::string> full_required_lines() {
  auto lines = minimal_lines();
  for (const char* line : {
           "drivers:",                  // 7
           "  - id: d1",                // 8
           "    protocol: sim",         // 9
           "runtime:",                  // 10
           "  auth:",                   // 11
           "    tokens:",               // 12
           "      - principal: alice",  // 13
           "        role: OWNER",       // 14
       })
    lines.emplace_back(line);
  lines.push_back("        sha256: " + kHash);  // 15
  return lines;
}

struct MissingCase {
  const char* key_path;
  std::vector<int> drop;  // 1-based lines removed
  int replace_line = 0;   // 1-based line replaced by `replacement` (0: none)
  const char* replacement = "";
  int line, column;  // expected mark: the parent mapping
};

}  // namespace

TEST_CASE("the base file for the missing-key cases is valid") { parse_ok(join(full_required_lines())); }

TEST_CASE("each required key missing is an error at its parent mapping") {
  const std::vector<MissingCase> cases = {
      {"rcan_version", {1}, 0, "", 1, 1},
      {"metadata", {2, 3, 4, 5, 6}, 0, "", 1, 1},
      {"metadata.robot_name", {3}, 0, "", 2, 1},
      {"drivers[0].protocol", {9}, 0, "", 8, 5},
      {"runtime.auth.tokens[0].principal", {14}, 13, "      - role: OWNER", 13, 9},
      {"runtime.auth.tokens[0].role", {14}, 0, "", 13, 9},
      {"runtime.auth.tokens[0].sha256", {15}, 0, "", 13, 9},
  };
  for (const auto& c : cases) {
    CAPTURE(c.key_path);
    std::vector<std::string> lines;
    const auto base = full_required_lines();
    for (int n = 1; n <= static_cast<int>(base.size()); ++n) {
      if (n == c.replace_line) lines.emplace_back(c.replacement);
      else if (std::find(c.drop.begin(), c.drop.end(), n) == c.drop.end()) lines.push_back(base[n - 1]);
    }
    const auto errors = parse_errors(join(lines));
    REQUIRE(errors.size() == 1);
    CHECK(errors[0].severity == ConfigDiagnostic::Severity::Error);
    CHECK(errors[0].key_path == c.key_path);
    CHECK(errors[0].mark.file == "test.rcan.yaml");
    CHECK(errors[0].mark.line == c.line);
    CHECK(errors[0].mark.column == c.column);
    CHECK(contains(errors[0].message, "is missing"));
    CHECK(contains(errors[0].format(), "test.rcan.yaml:" + std::to_string(c.line) + ":" + std::to_string(c.column) +
                                           ": error: " + c.key_path + ": required key"));
  }
}

TEST_CASE("the exact text of a type error") {
  auto lines = minimal_lines();
  lines.push_back("physics:");
  lines.push_back("  wheel_circumference_m: \"0.21\"");
  const auto errors = parse_errors(join(lines));
  REQUIRE(errors.size() == 1);
  CHECK(errors[0].format() ==
        "test.rcan.yaml:8:3: error: physics.wheel_circumference_m: expected a number, found the string \"0.21\"; "
        "remove the quotes to make it a number");
}

TEST_CASE("wrong types and out-of-range values name the key, what was expected and what was found") {
  struct TypeCase {
    std::string yaml;  // appended to the minimal file, from line 7
    std::string key_path;
    std::string expected_text;
    int line;
  };
  const std::vector<TypeCase> cases = {
      {"physics: {turn_time_per_deg_s: \"0.008\"}", "physics.turn_time_per_deg_s", "expected a number, found the string", 7},
      {"physics: {wheel_circumference_m: fast}", "physics.wheel_circumference_m", "expected a number, found the string \"fast\"",
       7},
      {"physics: {wheel_circumference_m: 0}", "physics.wheel_circumference_m", "must be greater than 0", 7},
      {"physics: {wheel_circumference_m: .inf}", "physics.wheel_circumference_m", "found the number .inf", 7},
      {"physics:\n  kinematics:\n    link: base", "physics.kinematics", "expected a sequence, found a mapping", 8},
      {"rcan_protocol: {capabilities: nav}", "rcan_protocol.capabilities", "expected a sequence, found the string \"nav\"", 7},
      {"rcan_protocol: {capabilities: [nav, \"\"]}", "rcan_protocol.capabilities[1]", "must not be empty", 7},
      {"rcan_protocol: {capabilities: [nav, ~]}", "rcan_protocol.capabilities[1]", "expected a string, found null", 7},
      {"rcan_protocol:\n  capabilities:", "rcan_protocol.capabilities", "write [] for an empty list", 8},
      {"rcan_protocol: {port: 70000}", "rcan_protocol.port", "must be between 0 and 65535, found the integer 70000", 7},
      {"rcan_protocol: {port: -1}", "rcan_protocol.port", "must be between 0 and 65535", 7},
      {"rcan_protocol: {port: \"8000\"}", "rcan_protocol.port", "expected an integer, found the string \"8000\"", 7},
      {"rcan_protocol: {enable_mdns: yes}", "rcan_protocol.enable_mdns", "expected a boolean (true or false)", 7},
      {"runtime: {listen: {port: 65536}}", "runtime.listen.port", "must be between 0 and 65535", 7},
      {"safety: {watchdog_ms: 0}", "safety.watchdog_ms", "must be greater than 0 and at most 2147483647, found the integer 0", 7},
      {"safety: {watchdog_ms: 500.5}", "safety.watchdog_ms", "expected an integer, found the number 500.5", 7},
      {"safety: {max_linear_speed: 1.5}", "safety.max_linear_speed", "must be between 0 and 1", 7},
      {"drivers: {id: x}", "drivers", "expected a sequence, found a mapping", 7},
      {"drivers:\n  - id: a\n    protocol: sim\n  - id: a\n    protocol: sim", "drivers[1].id",
       "duplicate value \"a\"; already used by drivers[0].id (line 8)", 10},
      {"runtime: {auth: {mode: tokne}}", "runtime.auth.mode",
       "must be one of tokens, open, found the string \"tokne\"; did you mean 'tokens'?", 7},
      {"runtime: {logging: {level: verbose}}", "runtime.logging.level", "must be one of trace, debug, info, warn, error", 7},
      {"runtime: {auth: {tokens: [{principal: a, role: admin, sha256: " + kHash + "}]}}", "runtime.auth.tokens[0].role",
       "must be one of GUEST, USER, LEASEE, OWNER, CREATOR (any case), found the string \"admin\"", 7},
      {"runtime: {auth: {tokens: [{principal: a, role: ownr, sha256: " + kHash + "}]}}", "runtime.auth.tokens[0].role",
       "did you mean 'OWNER'?", 7},
      {"runtime: {auth: {tokens: [{principal: a, role: user, sha256: " + std::string(64, 'A') + "}]}}",
       "runtime.auth.tokens[0].sha256", "upper-case", 7},
      {"runtime: {auth: {tokens: [{principal: a, role: user, sha256: " + std::string(64, 'g') + "}]}}",
       "runtime.auth.tokens[0].sha256", "not a hex digit", 7},
      {"runtime: {auth: {tokens: [{principal: a, role: user, sha256: abc123}]}}", "runtime.auth.tokens[0].sha256",
       "found a string of 6 characters", 7},
      {"runtime: {plugin_paths: plugins}", "runtime.plugin_paths", "expected a sequence", 7},
      {"runtime: {capabilities: {nav: 3}}", "runtime.capabilities.nav", "expected a mapping, found the integer 3", 7},
      {"camera: [a, b]", "camera", "expected a mapping, found a sequence", 7},
      {"runtime: {handler_timeout_ms: 99999999999}", "runtime.handler_timeout_ms",
       "must be greater than 0 and at most 2147483647", 7},
  };
  for (const auto& c : cases) {
    CAPTURE(c.yaml);
    auto lines = minimal_lines();
    lines.push_back(c.yaml);
    const auto errors = parse_errors(join(lines));
    REQUIRE(errors.size() == 1);
    CHECK(errors[0].key_path == c.key_path);
    CHECK(errors[0].mark.line == c.line);
    CHECK(errors[0].mark.column > 0);
    CHECK_MESSAGE(contains(errors[0].message, c.expected_text), errors[0].message);
  }
}

TEST_CASE("strings that look like numbers must be quoted; numbers where text is expected are errors") {
  auto lines = minimal_lines();
  lines[0] = "rcan_version: 1.3";
  lines[3] = "  robot_uuid: 00112233";
  const auto errors = parse_errors(join(lines));
  REQUIRE(errors.size() == 2);
  CHECK(errors[0].key_path == "rcan_version");
  CHECK(contains(errors[0].message, "expected a string, found the number 1.3; put it in quotes"));
  CHECK(errors[1].key_path == "metadata.robot_uuid");
  CHECK(contains(errors[1].message, "found the integer 112233"));
}

TEST_CASE("a token hash is never echoed, even when a plain token was pasted in its place") {
  auto lines = minimal_lines();
  lines.push_back("runtime:");
  lines.push_back("  auth:");
  lines.push_back("    tokens:");
  lines.push_back("      - {principal: a, role: OWNER, sha256: hunter2-plain-secret-token}");
  lines.push_back("      - {principal: b, role: OWNER, sha256: " + kHash + "}");
  lines.push_back("      - {principal: c, role: OWNER, sha256: " + kHash + "}");
  try {
    parse_robot_config(join(lines), "test.rcan.yaml", "/srv/robot");
    FAIL("expected a ConfigError");
  } catch (const ConfigError& e) {
    const std::string all = e.what();
    CHECK_FALSE(contains(all, "hunter2"));
    CHECK_FALSE(contains(all, kHash));
    REQUIRE(e.diagnostics().size() == 2);
    CHECK(e.diagnostics()[0].key_path == "runtime.auth.tokens[0].sha256");
    CHECK(e.diagnostics()[1].key_path == "runtime.auth.tokens[2].sha256");
    CHECK(contains(e.diagnostics()[1].message, "already used by runtime.auth.tokens[1].sha256"));
  }
}

TEST_CASE("an unknown key that is a near miss of a known one is an error naming it") {
  auto lines = minimal_lines();
  lines.push_back("phisics:");
  lines.push_back("  wheel_circumference_m: 0.2");
  try {
    parse_robot_config(join(lines), "test.rcan.yaml", "/srv/robot");
    FAIL("expected a ConfigError");
  } catch (const ConfigError& e) {
    REQUIRE(e.diagnostics().size() == 1);
    CHECK(e.diagnostics()[0].format() == "test.rcan.yaml:7:1: error: unknown key 'phisics'; did you mean 'physics'?");
  }
}

TEST_CASE("unknown keys in nested blocks: near misses are errors, the others one warning that lists them") {
  auto lines = minimal_lines();
  lines.push_back("physics:");                     // 7
  lines.push_back("  wheel_circumfrence_m: 0.2");  // 8
  lines.push_back("colour: red");                  // 9
  lines.push_back("plugin_paths: [x]");            // 10
  lines.push_back("runtime:");                     // 11
  lines.push_back("  auth:");                      // 12
  lines.push_back("    tokens:");                  // 13
  lines.push_back("      - principal: a");         // 14
  lines.push_back("        role: OWNER");          // 15
  lines.push_back("        sha256: " + kHash);     // 16
  lines.push_back("        rol: USER");            // 17
  try {
    parse_robot_config(join(lines), "test.rcan.yaml", "/srv/robot");
    FAIL("expected a ConfigError");
  } catch (const ConfigError& e) {
    const auto& d = e.diagnostics();
    REQUIRE(d.size() == 3);
    CHECK(d[0].format() ==
          "test.rcan.yaml:8:3: error: physics: unknown key 'wheel_circumfrence_m'; did you mean 'wheel_circumference_m'?");
    CHECK(d[1].severity == ConfigDiagnostic::Severity::Warning);  // both ignored keys, in one warning at the first
    CHECK(d[1].mark.line == 9);
    CHECK(d[1].message ==
          "2 keys of other RCAN versions or runtimes, not implemented by rcand (RCAN 1.3), ignored: colour (line 9), "
          "plugin_paths (line 10; rcand reads runtime.plugin_paths)");
    CHECK(d[2].severity == ConfigDiagnostic::Severity::Error);
    CHECK(d[2].key_path == "runtime.auth.tokens[0]");
    CHECK(contains(d[2].message, "did you mean 'role'?"));
  }
}

TEST_CASE("free-form places accept any key without a warning") {
  auto lines = minimal_lines();
  for (const char* line : {
           "drivers:",
           "  - id: wheels",
           "    protocol: pca9685",
           "    pwm_frequency_hz: 50",
           "    channels: {left: 0, whatever: {deep: 1}}",
           "camera:",
           "  device: /dev/video0",
           "network: {wifi: {ssid: x}}",
           "physics:",
           "  kinematics:",
           "    - {anything: goes}",
           "runtime:",
           "  capabilities:",
           "    nav: {max_speed: 0.4, custom: [1, 2]}",
           "    com.acme.gripper: {force_n: 5}",
           "  r2r: {origin: {x: 1, y: 2}, mqtt: {broker: localhost}}",
       })
    lines.emplace_back(line);
  const auto loaded = parse_ok(join(lines));
  CHECK(loaded.warnings.empty());
  CHECK(loaded.config.drivers.at(0).settings["channels"]["whatever"]["deep"] == 1);
  CHECK(loaded.config.runtime.capabilities["com.acme.gripper"]["force_n"] == 5);
}

TEST_CASE("several errors are all reported at once, in file order, with warnings") {
  const std::string yaml = R"(rcan_version: "1.3"
metadata:
  robot_name: r
  manufacturer: acme
physics:
  wheel_circumference_m: "0.21"
safety:
  watchdog_ms: -5
rcan_protocol:
  port: 99999
  enable_mdsn: true
)";
  try {
    parse_robot_config(yaml, "multi.rcan.yaml", "/srv/robot");
    FAIL("expected a ConfigError");
  } catch (const ConfigError& e) {
    const auto& d = e.diagnostics();
    REQUIRE(d.size() == 4);
    CHECK(d[0].key_path == "physics.wheel_circumference_m");
    CHECK(d[1].key_path == "safety.watchdog_ms");
    CHECK(d[2].key_path == "rcan_protocol.port");
    CHECK(d[3].severity == ConfigDiagnostic::Severity::Error);  // a near miss
    CHECK(contains(d[3].message, "did you mean 'enable_mdns'?"));
    CHECK(errors_only(d).size() == 4);
    // what() is every diagnostic, one per line.
    const std::string what = e.what();
    CHECK(std::count(what.begin(), what.end(), '\n') == 3);
    CHECK(contains(what, "multi.rcan.yaml:6:3: error: physics.wheel_circumference_m: expected a number"));
    CHECK(contains(what, "multi.rcan.yaml:11:3: error: rcan_protocol: unknown key 'enable_mdsn'"));
  }
}

TEST_CASE("a YAML syntax error reports its line") {
  auto lines = minimal_lines();
  lines.push_back("physics:");
  lines.push_back("  wheel_circumference_m: 0.21");
  lines.push_back(" turn_time_per_deg_s: 0.008");  // line 9: bad indentation
  const auto errors = parse_errors(join(lines));
  REQUIRE(errors.size() == 1);
  CHECK(errors[0].mark.line == 9);
  CHECK(errors[0].mark.column > 0);
  CHECK(contains(errors[0].message, "YAML syntax error"));
  CHECK(contains(errors[0].format(), "test.rcan.yaml:9:"));
}

TEST_CASE("duplicate keys are errors, reported with the first occurrence") {
  auto lines = minimal_lines();
  lines.push_back("metadata:");
  const auto errors = parse_errors(join(lines));
  REQUIRE(errors.size() == 1);
  CHECK(errors[0].key_path == "metadata");
  CHECK(errors[0].mark.line == 7);
  CHECK(contains(errors[0].message, "first written at line 2"));
}

TEST_CASE("an empty file, a comment-only file and a non-mapping document are errors") {
  for (const std::string& yaml : {std::string(""), std::string("# nothing here\n\n")}) {
    const auto errors = parse_errors(yaml);
    REQUIRE(errors.size() == 1);
    CHECK(contains(errors[0].message, "empty"));
    CHECK(errors[0].mark.line == 1);
  }
  const auto list = parse_errors("- a\n- b\n");
  REQUIRE(list.size() == 1);
  CHECK(contains(list[0].message, "expected a mapping"));
  CHECK(contains(list[0].message, "found a sequence"));

  const auto two_docs = parse_errors(join(minimal_lines()) + "---\nrcan_version: \"1.3\"\n");
  REQUIRE(two_docs.size() == 1);
  CHECK(contains(two_docs[0].message, "one YAML document"));
}

TEST_CASE("hostile input fails cleanly") {
  SUBCASE("alias expansion bomb") {
    std::string yaml = join(minimal_lines()) + "camera:\n  a: &a [x, x, x, x, x, x, x, x, x, x]\n";
    for (char c = 'b'; c <= 'g'; ++c) {
      const char prev = static_cast<char>(c - 1);
      yaml += std::string("  ") + c + ": &" + c + " [";
      for (int i = 0; i < 10; ++i) yaml += std::string(i ? ", *" : "*") + prev;
      yaml += "]\n";
    }
    const auto errors = parse_errors(yaml);
    REQUIRE(errors.size() == 1);
    CHECK(contains(errors[0].message, "too large"));
  }
  SUBCASE("invalid UTF-8") {
    auto lines = minimal_lines();
    lines[2] = "  robot_name: \"rover\xff\"";
    const auto errors = parse_errors(join(lines));
    REQUIRE(errors.size() == 1);
    CHECK(errors[0].mark.line == 3);
    CHECK(contains(errors[0].message, "UTF-8"));
  }
  SUBCASE("deep nesting") {
    const std::string yaml = join(minimal_lines()) + "camera: " + std::string(200, '[') + std::string(200, ']') + "\n";
    CHECK_FALSE(errors_only(parse_errors(yaml)).empty());
  }
  SUBCASE("a stray flow comma (yaml-cpp's LoadAll yields documents forever on it; found by fuzz_rcan_yaml)") {
    for (const std::string& yaml : std::vector<std::string>{",", ",%", join(minimal_lines()) + ",\n"}) {
      CAPTURE(yaml);
      CHECK_FALSE(errors_only(parse_errors(yaml)).empty());  // an error, and in particular an answer
    }
  }
  SUBCASE("a non-scalar key") {
    const auto errors = parse_errors(join(minimal_lines()) + "camera: {[a]: 1}\n");
    REQUIRE(errors.size() == 1);
    CHECK(contains(errors[0].message, "key must be a plain name"));
  }
}

// One loopback rule (libs/rcan/loopback.hpp) for config validation and for the kernel at startup: a name such as
// "localhost" is not a loopback address to either, so a file that validates also starts.
TEST_CASE("open auth mode: only a literal loopback listen address validates, the same rule the kernel applies") {
  auto with_listen = [](const std::string& address) {
    auto lines = minimal_lines();
    lines.emplace_back("runtime:");
    lines.emplace_back("  listen: {address: \"" + address + "\"}");
    lines.emplace_back("  auth: {mode: open}");
    return join(lines);
  };
  for (const char* address : {"127.0.0.1", "127.0.0.2", "::1", "::ffff:127.0.0.1"}) {
    CAPTURE(address);
    parse_ok(with_listen(address));
    CHECK(rcand::is_loopback_address(address));
  }
  for (const char* address : {"localhost", "0.0.0.0", "192.168.1.10", "::", "::ffff:10.0.0.1"}) {
    CAPTURE(address);
    CHECK_THROWS_AS(parse_robot_config(with_listen(address), "robot.rcan.yaml", "."), ConfigError);
    CHECK_FALSE(rcand::is_loopback_address(address));
  }
}

// Issue 28 item 4: the camera block was free-form, so `framrate: 5` was dropped without a word and the camera ran at 30.
TEST_CASE("the camera block: a misspelled key is an error at its line, other runtimes' keys a warning, ours accepted") {
  SUBCASE("typos") {
    for (const auto& line_key_guess_case : std::vector<std::tuple<std::string, std::string, std::string>>{
             {"  framrate: 5", "framrate", "framerate"},
             {"  tyep: usb", "tyep", "type"},
             {"  devcie: /dev/video2", "devcie", "device"},
             {"  resolutoin: [320, 240]", "resolutoin", "resolution"}}) {
      const auto& line = std::get<0>(line_key_guess_case);  // clang 14: CAPTURE's lambda cannot capture a structured binding
      const auto& key = std::get<1>(line_key_guess_case);
      const auto& guess = std::get<2>(line_key_guess_case);
      CAPTURE(line);
      auto lines = minimal_lines();
      lines.emplace_back("camera:");  // line 7
      lines.emplace_back("  fps: 15");
      lines.push_back(line);  // line 9
      const auto errors = errors_only(parse_errors(join(lines)));
      REQUIRE(errors.size() == 1);
      CHECK(errors[0].mark.line == 9);
      CHECK(errors[0].mark.column == 3);
      CHECK(errors[0].format() == "test.rcan.yaml:9:3: error: camera: unknown key '" + key + "'; did you mean '" + guess + "'?");
    }
  }
  SUBCASE("a wrong type is left to vision's manifest schema, which reports it with every other problem") {
    // (tests/configs/first-try/camera-ollama.rcan.yaml: camera.resolution "640x480" beside the chat block's errors)
    auto lines = minimal_lines();
    lines.emplace_back("camera:");
    lines.emplace_back("  fps: fast");
    CHECK(parse_ok(join(lines)).warnings.empty());
  }
  SUBCASE("every key the vision plugin reads, and the reference runtime's own keys") {
    auto lines = minimal_lines();
    for (const char* line :
         {"camera:", "  type: usb", "  device: 2", "  url: http://cam/stream", "  path: a.avi", "  file: a.avi",
          "  resolution: [320, 240]", "  width: 320", "  height: 240", "  fps: 15", "  framerate: 15", "  fourcc: MJPG",
          "  depth: synthetic", "  depth_enabled: true", "  camera_required: false"})
      lines.emplace_back(line);
    const auto loaded = parse_ok(join(lines));
    REQUIRE(loaded.warnings.size() == 1);  // the one warning listing ignored keys
    CHECK(contains(loaded.warnings[0].message, "camera.depth_enabled (line 20; another runtime's, rcand reads camera.depth)"));
    CHECK(contains(loaded.warnings[0].message, "camera.camera_required (line 21"));
  }
}
