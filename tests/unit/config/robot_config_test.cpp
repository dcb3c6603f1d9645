// A valid file becomes the right RobotConfig: values, defaults, paths, marks.
#include "config_test_support.hpp"

#include "libs/config/config_reference.hpp"
#include "libs/rcan/machine_identity.hpp"
#include "temp_dir.hpp"

#include <doctest/doctest.h>

#include <cmath>
#include <limits>

using namespace config_test;
using rcand::closest_match;
using rcand::config::RobotConfig;

namespace {

const std::string kFullConfig = R"(rcan_version: "1.3"
metadata:
  robot_name: rover-1
  robot_uuid: "4f3c2a1b-0000-4000-8000-000000000001"
  manufacturer: acme
  model: rover
  ruri: "rcan://local.rcan/acme/rover/4f3c2a1b"
  description: test rover
agent:
  provider: ollama
  model: llava
  latency_budget_ms: 200
  min_obstacle_m: 0.3
physics:
  type: wheeled
  dof: 2
  wheel_circumference_m: 0.21
  turn_time_per_deg_s: 0.008
  max_wheel_rps: 2
  wheel_base_m: 0.15
  kinematics:
    - {link: base, length_m: 0.1}
drivers:
  - id: wheels
    protocol: pca9685
    address: 0x40
    channels: {left: 0, right: 1}
    pwm_frequency_hz: 50
  - id: arm
    protocol: dynamixel
    port: /dev/ttyUSB0
    baud_rate: 1000000
camera:
  device: /dev/video0
network:
  hostname: rover-1
rcan_protocol:
  port: 8001
  capabilities: [nav, teleop, status]
  enable_mdns: true
  enable_jwt: false
safety:
  estop_on_startup: true
  watchdog_ms: 250
  max_linear_speed: 0.5
runtime:
  listen: {address: 0.0.0.0, port: 9000}
  plugin_paths: [plugins, /opt/rcand/plugins, ../shared/plugins]
  auth:
    mode: tokens
    jwt_secret_file: secrets/jwt.key
    tokens:
      - principal: alice
        role: owner
        sha256: 4c5dc9b7708905f77f5e5d16316b5dfb425e68cb326dcd55a860e90a7707031e
      - principal: bob
        role: Guest
        sha256: "0000000000000000000000000000000000000000000000000000000000000000"  # all digits: quoted, else an integer
  logging: {level: debug}
  swarm_file: swarm.yaml
  handler_timeout_ms: 5000
  capabilities:
    nav: {max_speed: 0.5}
    vision:
  r2r: {udp_port: 9100, status_interval_ms: 500}
)";

}  // namespace

TEST_CASE("a full valid config round-trips into RobotConfig") {
  const auto loaded = parse_ok(kFullConfig);
  CHECK(loaded.warnings.empty());
  const RobotConfig& c = loaded.config;

  CHECK(c.rcan_version == "1.3");
  CHECK(c.robot_name == "rover-1");
  CHECK(c.robot_uuid == "4f3c2a1b-0000-4000-8000-000000000001");
  CHECK(c.manufacturer == "acme");
  CHECK(c.model == "rover");
  REQUIRE(c.ruri.has_value());
  CHECK(*c.ruri == "rcan://local.rcan/acme/rover/4f3c2a1b");
  CHECK(c.has_agent);
  CHECK(c.has_camera);
  CHECK(*c.wheel_circumference_m == doctest::Approx(0.21));
  CHECK(*c.turn_time_per_deg_s == doctest::Approx(0.008));
  CHECK(c.max_wheel_rps == doctest::Approx(2.0));  // an integer is fine where a number is expected
  CHECK(c.has_kinematics);

  REQUIRE(c.drivers.size() == 2);
  CHECK(c.drivers[0].id == "wheels");
  CHECK(c.drivers[0].protocol == "pca9685");
  CHECK(c.drivers[0].settings["address"] == 64);  // plain 0x40 is a YAML 1.2 integer
  CHECK(c.drivers[0].settings["channels"]["right"] == 1);
  CHECK(c.drivers[0].settings["pwm_frequency_hz"] == 50);
  CHECK(c.drivers[0].settings["id"] == "wheels");  // settings is the whole entry
  CHECK(c.drivers[1].settings["baud_rate"] == 1000000);

  CHECK(c.rcan_port == 8001);
  REQUIRE(c.capabilities.has_value());
  CHECK(*c.capabilities == std::vector<std::string>{"nav", "teleop", "status"});
  CHECK(c.enable_mdns);
  CHECK_FALSE(c.enable_jwt);
  CHECK(c.estop_on_startup);

  const auto& r = c.runtime;
  CHECK(r.listen_address == "0.0.0.0");
  CHECK(c.listen_port() == 9000);
  REQUIRE(r.plugin_paths.size() == 3);
  CHECK(r.plugin_paths[0] == "/srv/robot/plugins");
  CHECK(r.plugin_paths[1] == "/opt/rcand/plugins");
  CHECK(r.plugin_paths[2] == "/srv/shared/plugins");
  CHECK(r.auth.mode == "tokens");
  REQUIRE(r.auth.jwt_secret_file.has_value());
  CHECK(*r.auth.jwt_secret_file == "/srv/robot/secrets/jwt.key");
  REQUIRE(r.auth.tokens.size() == 2);
  CHECK(r.auth.tokens[0].principal == "alice");
  CHECK(r.auth.tokens[0].role == "OWNER");  // canonical, whatever case was written
  CHECK(r.auth.tokens[0].sha256_hex == kHash);
  CHECK(r.auth.tokens[1].role == "GUEST");
  CHECK(r.log_level == "debug");
  CHECK(r.swarm_file == "/srv/robot/swarm.yaml");
  CHECK(r.handler_timeout_ms == 5000);
  CHECK(r.capabilities["nav"]["max_speed"] == 0.5);
  CHECK(r.capabilities["vision"] == nlohmann::json::object());  // `vision:` with no settings
  CHECK(r.r2r["udp_port"] == 9100);
}

TEST_CASE("a minimal config gets every default, and doc holds only what was written") {
  const auto loaded = parse_ok(join(minimal_lines()));
  const RobotConfig& c = loaded.config;
  CHECK(loaded.warnings.empty());
  CHECK(c.source_file == "test.rcan.yaml");
  CHECK_FALSE(c.ruri.has_value());
  CHECK_FALSE(c.has_agent);
  CHECK_FALSE(c.has_camera);
  CHECK_FALSE(c.wheel_circumference_m.has_value());
  CHECK_FALSE(c.turn_time_per_deg_s.has_value());
  CHECK(c.max_wheel_rps == 1.0);
  CHECK_FALSE(c.has_kinematics);
  CHECK(c.drivers.empty());
  CHECK(c.rcan_port == 8000);
  CHECK(c.listen_port() == 8000);
  CHECK_FALSE(c.capabilities.has_value());
  CHECK_FALSE(c.enable_mdns);
  CHECK(c.enable_jwt);
  CHECK_FALSE(c.estop_on_startup);
  CHECK(c.runtime.listen_address == "127.0.0.1");
  CHECK_FALSE(c.runtime.listen_port.has_value());
  CHECK(c.runtime.plugin_paths.empty());
  CHECK(c.runtime.auth.mode == "tokens");
  CHECK_FALSE(c.runtime.auth.jwt_secret_file.has_value());
  CHECK(c.runtime.auth.tokens.empty());
  CHECK(c.runtime.log_level == "info");
  CHECK(c.runtime.swarm_file == "/etc/rcand/swarm.yaml");
  CHECK(c.runtime.handler_timeout_ms == 10000);
  CHECK(c.runtime.capabilities == nlohmann::json::object());
  CHECK(c.runtime.r2r == nlohmann::json::object());

  CHECK(c.doc.size() == 2);
  CHECK_FALSE(c.doc.contains("rcan_protocol"));
  CHECK(c.doc["metadata"]["robot_uuid"] == "abcd1234");
}

TEST_CASE("listen port falls back to rcan_protocol.port") {
  auto lines = minimal_lines();
  lines.push_back("rcan_protocol: {port: 8123}");
  CHECK(parse_ok(join(lines)).config.listen_port() == 8123);
}

TEST_CASE("rcan_protocol.capabilities: absent means auto-detect, [] means none") {
  auto lines = minimal_lines();
  lines.push_back("rcan_protocol: {port: 8000}");
  CHECK_FALSE(parse_ok(join(lines)).config.capabilities.has_value());

  lines.back() = "rcan_protocol: {capabilities: []}";
  const auto empty = parse_ok(join(lines)).config.capabilities;
  REQUIRE(empty.has_value());
  CHECK(empty->empty());

  lines.back() = "rcan_protocol: {capabilities: [status, com.acme.gripper]}";
  CHECK(*parse_ok(join(lines)).config.capabilities == std::vector<std::string>{"status", "com.acme.gripper"});
}

TEST_CASE("robot_uuid may be left out when ruri is given") {
  auto lines = minimal_lines();
  lines[3] = "  ruri: \"rcan://acme.rover.abcd1234\"";
  const auto c = parse_ok(join(lines)).config;
  CHECK(c.robot_uuid.empty());
  CHECK(c.ruri == "rcan://acme.rover.abcd1234");
}

TEST_CASE("robot_uuid left out, or the all-zero placeholder, is derived from /etc/machine-id") {
  const auto derived = rcand::robot_uuid_from_machine_id();
  if (!derived) {
    MESSAGE("SKIPPED: no /etc/machine-id on this machine");
    return;
  }
  auto lines = minimal_lines();
  lines.erase(lines.begin() + 3);  // robot_uuid
  CHECK(parse_ok(join(lines)).config.robot_uuid == *derived);
  lines.insert(lines.begin() + 3, "  robot_uuid: 00000000-0000-4000-8000-000000000000");
  CHECK(parse_ok(join(lines)).config.robot_uuid == *derived);
}

TEST_CASE("the derived robot_uuid is UUID-shaped, app-specific and stable; a bad machine id gives none") {
  rcand::test::TempDir dir;
  const auto a = rcand::robot_uuid_from_machine_id(dir.write("a", "3d1219c7c4c5404aaa1f6d2a48adfda4\n"));
  const auto b = rcand::robot_uuid_from_machine_id(dir.write("b", "0123456789abcdef0123456789abcdef\n"));
  REQUIRE(a.has_value());
  REQUIRE(b.has_value());
  CHECK(a == rcand::robot_uuid_from_machine_id(dir.path() / "a"));  // stable
  CHECK(*a != *b);
  CHECK(a->size() == 36);
  CHECK(a->at(14) == '4');                                          // version 4 shape
  CHECK(std::string("89ab").find(a->at(19)) != std::string::npos);  // RFC 4122 variant
  CHECK(a->find("3d1219c7") == std::string::npos);                  // the machine id itself is not exposed
  CHECK_FALSE(rcand::robot_uuid_from_machine_id(dir.write("short", "3d1219c7\n")).has_value());
  CHECK_FALSE(rcand::robot_uuid_from_machine_id(dir.path() / "missing").has_value());
  CHECK(rcand::is_placeholder_uuid("00000000-0000-0000-0000-000000000000"));
  CHECK_FALSE(rcand::is_placeholder_uuid("4f3c2a1b-0000-4000-8000-000000000001"));
}

// Nav reads the alias itself (plugins/nav/nav_test.cpp); the config only warns when both are written and disagree.
TEST_CASE("safety.obstacle_stop_cm is an alias of agent.min_obstacle_m") {
  auto lines = minimal_lines();
  lines.push_back("safety: {obstacle_stop_cm: 25}");
  const auto loaded = parse_ok(join(lines));
  CHECK(loaded.warnings.empty());

  lines.push_back("agent: {min_obstacle_m: 0.4}");
  const auto both = parse_ok(join(lines));
  REQUIRE(both.warnings.size() == 1);
  CHECK(both.warnings[0].key_path == "safety.obstacle_stop_cm");
  CHECK(both.warnings[0].message.find("agent.min_obstacle_m") != std::string::npos);
}

TEST_CASE("open auth mode is accepted on loopback only") {
  auto lines = minimal_lines();
  lines.push_back("runtime:");
  lines.push_back("  auth: {mode: open}");
  CHECK(parse_ok(join(lines)).config.runtime.auth.mode == "open");

  lines.push_back("  listen: {address: \"::1\"}");
  CHECK(parse_ok(join(lines)).config.runtime.listen_address == "::1");

  lines.back() = "  listen: {address: 0.0.0.0}";
  const auto errors = parse_errors(join(lines));
  REQUIRE(errors.size() == 1);
  CHECK(errors[0].key_path == "runtime.auth.mode");
  CHECK(errors[0].mark.line == 8);
  CHECK(errors[0].message.find("loopback") != std::string::npos);
}

TEST_CASE("marks record where every key and item was written") {
  const auto c = parse_ok(kFullConfig).config;
  CHECK(c.marks.at("physics.wheel_circumference_m").line == 17);
  CHECK(c.marks.at("physics.wheel_circumference_m").column == 3);
  CHECK(c.marks.at("physics.wheel_circumference_m").file == "test.rcan.yaml");
  CHECK(c.marks.at("drivers[0].protocol").line == 25);
  CHECK(c.marks.at("drivers[0].protocol").column == 5);
  CHECK(c.marks.at("drivers[1]").line == 29);
  CHECK(c.marks.at("rcan_protocol.capabilities[2]").line == 39);
  CHECK(c.marks.at("drivers[0].channels.right").line == 27);  // free-form blocks are marked too

  // mark_of falls back to the nearest written ancestor.
  CHECK(c.mark_of("drivers[0].channels.middle").line == 27);
  CHECK(c.mark_of("physics.nope").line == 14);
  CHECK(c.mark_of("nothing.here").line == 1);
}

TEST_CASE("plain and quoted scalars convert like YAML 1.2 core") {
  auto lines = minimal_lines();
  lines.push_back("network:");  // free-form: any key, any value
  lines.push_back("  a: ~");
  lines.push_back("  b: null");
  lines.push_back("  c: true");
  lines.push_back("  d: \"true\"");
  lines.push_back("  e: -42");
  lines.push_back("  f: 1.5e3");
  lines.push_back("  g: '7'");
  lines.push_back("  h: hello world");
  lines.push_back("  i: 0o17");
  lines.push_back("  j: |\n    text\n");
  for (const char* line : {"  k: +5", "  l: .5", "  m: 1.", "  n: 1e", "  o: 0x1F", "  p: -.inf", "  q: .nan", "  r: 1_000",
                           "  s: 12abc", "  t: 9223372036854775808", "  u: -0.25e-2", "  v: 2021-01-01"})
    lines.emplace_back(line);
  const auto doc = parse_ok(join(lines)).config.doc["network"];
  CHECK(doc["a"].is_null());
  CHECK(doc["b"].is_null());
  CHECK(doc["c"] == true);
  CHECK(doc["d"] == "true");
  CHECK(doc["e"] == -42);
  CHECK(doc["f"].is_number_float());
  CHECK(doc["f"] == 1500.0);
  CHECK(doc["g"] == "7");
  CHECK(doc["h"] == "hello world");
  CHECK(doc["i"] == 15);
  CHECK(doc["j"] == "text\n");
  CHECK(doc["k"] == 5);
  CHECK(doc["l"] == 0.5);
  CHECK(doc["m"] == 1.0);
  CHECK(doc["m"].is_number_float());
  CHECK(doc["n"] == "1e");
  CHECK(doc["o"] == 31);
  CHECK(doc["p"].get<double>() == -std::numeric_limits<double>::infinity());
  CHECK(std::isnan(doc["q"].get<double>()));
  CHECK(doc["r"] == "1_000");
  CHECK(doc["s"] == "12abc");
  CHECK(doc["t"].is_number_unsigned());
  CHECK(doc["u"] == doctest::Approx(-0.0025));
  CHECK(doc["v"] == "2021-01-01");
}

TEST_CASE("closest_match suggests plausible typos only") {
  const std::vector<std::string> keys{"rcan_version", "metadata", "physics", "drivers", "runtime"};
  CHECK(closest_match("phisics", keys) == "physics");
  CHECK(closest_match("Physics", keys) == "physics");
  CHECK(closest_match("metdaata", keys) == "metadata");  // a swapped pair is one edit
  CHECK(closest_match("driver", keys) == "drivers");
  CHECK(closest_match("runtim", keys) == "runtime");
  CHECK(closest_match("zebra", keys) == std::nullopt);
  CHECK(closest_match("", keys) == std::nullopt);
  CHECK(closest_match("x", {}) == std::nullopt);
  CHECK(closest_match("wheel_circ", {"wheel_base_m", "wheel_circumference_m"}) == "wheel_circumference_m");
}

TEST_CASE("config_reference lists every key from the validating table") {
  const std::string text = rcand::config::config_reference();
  CHECK(text.find("physics.wheel_circumference_m") != std::string::npos);
  CHECK(text.find("runtime.auth.tokens[].sha256") != std::string::npos);
  const auto port = text.substr(text.find("rcan_protocol.port"));
  CHECK(port.substr(0, port.find('\n')).find("default 8000") != std::string::npos);
  const auto name = text.substr(text.find("metadata.robot_name"));
  CHECK(name.substr(0, name.find('\n')).find("required") != std::string::npos);
}

TEST_CASE("a close value gets a suggestion too") {
  auto lines = minimal_lines();
  lines.push_back("runtime: {logging: {level: warning}}");
  const auto errors = parse_errors(join(lines));
  REQUIRE(errors.size() == 1);
  CHECK(errors[0].message.find("did you mean 'warn'?") != std::string::npos);
}
