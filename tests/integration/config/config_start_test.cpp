// rcand --check-config against a real start (docs/protocol.md §10.4): a config that passes --check-config must not
// fail at start for any reason --check-config could have seen. Every config of tests/configs/ (the other runtimes'
// presets and the first-try hardware configs) that passes is started for real: Dynamixel buses on a pseudo-terminal
// with the servo emulator answering for the configured ids, Arduino bridges on a pseudo-terminal with the bridge
// firmware's emulator, every other device (I2C bus, GPIO chip, /OE chip, V4L2
// camera) pointed at a path that does not exist. Then every driver and capability must be running, or have failed
// because its device is absent - never for a setting. Also: the bundled config with vision left out is refused, by
// --check-config and by a start, at camera.depth; and every example `rcand --describe` prints passes --check-config.
#include <doctest/doctest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "libs/config/robot_config.hpp"
#include "libs/yaml/yaml_document.hpp"
#include "rcand_process.hpp"
#include "testing/arduino_emulator.hpp"
#include "testing/arduino_pty.hpp"
#include "testing/pty_pair.hpp"
#include "testing/servo_emulator.hpp"
#include "testing/sts_emulator.hpp"

using nlohmann::json;
using namespace rcand::test;
namespace dxl = rcand::plugins::dynamixel::testing;
namespace bridge = rcand::plugins::arduino::testing;

namespace {

std::vector<std::filesystem::path> corpus_files() {
  std::vector<std::filesystem::path> files;
  for (const auto& item :
       std::filesystem::recursive_directory_iterator(std::filesystem::path(RCAND_SOURCE_DIR) / "tests" / "configs"))
    // opencastor/ too: the reference runtime's presets as they are (groq_rover's and dynamixel_arm's confidence gate
    // of scope `safety` once passed --check-config and refused to start).
    if (item.path().string().ends_with(".rcan.yaml")) files.push_back(item.path());
  std::sort(files.begin(), files.end());
  return files;
}

ProcessResult check(const std::filesystem::path& file) {
  return run_tool(rcand_binary(), {"--check-config", file.string(), "--plugin-path", plugin_dir().string()});
}

// An emulator is a thread of this test, which a loaded machine (ctest -j2 under ASan) may not run for tens of
// milliseconds: its replies get the margin a slow USB adapter would, so that a start fails only for the config.
constexpr int kEmulatorReplyMs = 200;

// The fake or absent hardware a corpus config starts on.
struct Bench {
  TempDir dir{"rcand-config-start"};
  std::vector<std::unique_ptr<dxl::PtyPair>> ptys;
  std::vector<std::unique_ptr<dxl::ServoEmulator>> emulators;
  std::vector<std::unique_ptr<rcand::plugins::feetech::testing::StsEmulator>> sts_emulators;
  std::vector<std::unique_ptr<bridge::ArduinoPty>> arduino_ptys;
  std::vector<std::unique_ptr<bridge::ArduinoEmulator>> arduinos;

  std::string absent(const std::string& name) const { return (dir.path() / ("absent-" + name)).string(); }

  // `doc` with its devices replaced and test credentials, ready for RcandProcess.
  json prepare(json doc) {
    json none = json::array();
    for (auto& driver : doc.contains("drivers") && doc["drivers"].is_array() ? doc["drivers"] : none) {
      const std::string protocol = driver.value("protocol", "");
      if (protocol.starts_with("dynamixel")) {
        std::vector<std::uint8_t> ids;
        for (const auto& servo : driver.value("servos", json::array()))
          if (servo.contains("id") && servo["id"].is_number_integer()) ids.push_back(servo["id"].get<std::uint8_t>());
        auto& pty = ptys.emplace_back(std::make_unique<dxl::PtyPair>());
        emulators.push_back(std::make_unique<dxl::ServoEmulator>(pty->master(), ids));
        driver["port"] = pty->slave_path();
        driver["reply_timeout_ms"] = kEmulatorReplyMs;
      } else if (protocol == "feetech") {
        std::vector<std::uint8_t> ids;
        for (const auto& servo : driver.value("servos", json::array()))
          if (servo.contains("id") && servo["id"].is_number_integer()) ids.push_back(servo["id"].get<std::uint8_t>());
        auto& pty = ptys.emplace_back(std::make_unique<dxl::PtyPair>());
        sts_emulators.push_back(std::make_unique<rcand::plugins::feetech::testing::StsEmulator>(pty->master(), ids));
        driver["port"] = pty->slave_path();
        driver["reply_timeout_ms"] = kEmulatorReplyMs;
      } else if (protocol == "arduino_serial_json") {
        auto& pty = arduino_ptys.emplace_back(std::make_unique<bridge::ArduinoPty>());
        arduinos.push_back(std::make_unique<bridge::ArduinoEmulator>(pty->master()));
        driver["port"] = pty->slave_path();
      } else if (protocol.starts_with("pca9685")) {
        driver["port"] = absent("i2c");
        if (driver.contains("oe_chip")) driver["oe_chip"] = absent("oe-gpiochip");
      } else if (protocol == "gpio" || protocol == "l298n") {
        driver["chip"] = absent("gpiochip");
      }
    }
    if (doc.contains("camera") && doc["camera"].is_object() && !doc["camera"].contains("url") && !doc["camera"].contains("path"))
      doc["camera"]["device"] = absent("video0");
    json capabilities = doc.contains("runtime") ? doc["runtime"].value("capabilities", json()) : json();
    doc["runtime"] = sim_config()["runtime"];
    doc["runtime"].erase("state_dir");
    doc["runtime"].erase("plugin_paths");
    if (!capabilities.is_null()) doc["runtime"]["capabilities"] = capabilities;
    return doc;
  }
};

// Every instance the status lists that failed, with its reason.
std::vector<std::string> failures(const json& status) {
  std::vector<std::string> out;
  for (const auto& driver : status.value("drivers", json::array()))
    if (driver.value("state", "") == "failed")
      out.push_back("driver " + driver.value("id", "") + ": " + driver.value("reason", ""));
  const json capabilities = status.value("capabilities", json::object());
  for (const auto& [name, capability] : capabilities.items())
    if (capability.is_object() && capability.value("state", "") == "failed")
      out.push_back("capability " + name + ": " + capability.value("reason", ""));
  return out;
}

}  // namespace

TEST_CASE("every config that passes --check-config starts, and nothing in it fails for a reason --check-config could see") {
  std::size_t started = 0, refused = 0;
  for (const auto& file : corpus_files()) {
    INFO(file.filename().string());
    const auto checked = check(file);
    if (checked.exit_code != 0) {
      ++refused;
      continue;
    }
    Bench bench;
    const json doc = bench.prepare(rcand::config::load_robot_config(file).config.doc);
    std::unique_ptr<RcandProcess> robot;
    try {
      robot = std::make_unique<RcandProcess>(doc);
    } catch (const std::exception& e) {
      FAIL_CHECK("passed --check-config but did not start: " << e.what());
      continue;
    }
    ++started;
    const json status = robot->json("GET", "/api/status", "owner-token");
    REQUIRE(status.is_object());
    bool device_absent = false;  // a driver's absent device: its actuator is missing too, which the capabilities say
    for (const auto& failure : failures(status)) {
      INFO(failure);
      const bool absent = failure.find(bench.dir.path().string() + "/absent-") != std::string::npos;
      device_absent = device_absent || (absent && failure.starts_with("driver "));
      const bool follows = device_absent && failure.starts_with("capability ") &&
                           failure.find("actuator, and no configured driver provides one") != std::string::npos;
      CHECK_MESSAGE((absent || follows), "failed at start for a reason other than its absent device");
    }
  }
  MESSAGE(started << " configs started, " << refused << " refused by --check-config");
  CHECK(started >= 15);
  CHECK(refused >= 20);  // the first-try mistakes and other runtimes' configs rcand cannot run
}

TEST_CASE("the bundled config with vision left out: refused at camera.depth by --check-config and by a start") {
  const std::filesystem::path bundled = std::filesystem::path(RCAND_SOURCE_DIR) / "config" / "sim-rover.rcan.yaml";
  std::ifstream in(bundled);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string list = "capabilities: [status, teleop, nav, vision, arm, chat, com.acme.gripper]";
  REQUIRE(text.find(list) != std::string::npos);
  text.replace(text.find(list), list.size(), "capabilities: [status, teleop, nav, arm, chat, com.acme.gripper]");
  const std::string state = "state_dir: ../build/state";
  REQUIRE(text.find(state) != std::string::npos);
  text.replace(text.find(state), state.size(), "state_dir: state");
  std::size_t depth_line = 1;
  for (std::size_t i = 0; i < text.find("  depth: synthetic"); ++i) depth_line += text[i] == '\n';
  TempDir dir{"rcand-no-vision"};
  std::filesystem::copy_file(bundled.parent_path() / "dev-jwt.secret", dir.path() / "dev-jwt.secret");
  const auto file = dir.write("robot.rcan.yaml", text);
  const std::string expected = "robot.rcan.yaml:" + std::to_string(depth_line) +
                               ":3: error: camera.depth: camera.depth is set, so capability teleop and capability nav need the "
                               "depth zones (rcand.obstacle_source/1), which nothing this robot starts offers: add capability "
                               "vision (plugin org.rcand.vision) to rcan_protocol.capabilities, or remove camera.depth";
  const auto checked = check(file);
  INFO(checked.out, checked.err);
  CHECK(checked.exit_code == 1);
  CHECK(checked.err.find(expected) != std::string::npos);
  // A start refuses the same way, before anything is started.
  // (Under timeout(1): were it to start, it would serve until stopped.)
  const auto started = run_tool("/usr/bin/timeout", {"20", rcand_binary(), "--config", file.string(), "--plugin-path",
                                                     plugin_dir().string(), "--port", "0"});
  INFO(started.err);
  CHECK(started.exit_code == 1);
  CHECK(started.err.find(expected) != std::string::npos);
  CHECK(started.err.find("rcand: configuration invalid; not started") != std::string::npos);
  CHECK(started.out.find("listening") == std::string::npos);
}

namespace {

// The robot an example block is checked on: drives, an arm and a gripper, joints in physics.kinematics, and every
// capability whose example is shown listed.
json example_base() {
  json config = sim_config();
  config["drivers"] = json::array({{{"id", "drive0"}, {"protocol", "sim_diff_drive"}},
                                   {{"id", "arm0"}, {"protocol", "sim_arm"}},
                                   {{"id", "gripper0"}, {"protocol", "acme_gripper_sim"}}});
  config.erase("camera");
  config["physics"]["kinematics"] = json::array();
  for (const char* joint : {"base", "shoulder", "elbow", "wrist", "gripper"})
    config["physics"]["kinematics"].push_back({{"joint", joint}, {"min_deg", -170}, {"max_deg", 170}});
  return config;
}

void merge_example(json& config, const json& example, const std::string& id) {
  for (const auto& [key, value] : example.items()) {
    if (key == "drivers") {
      for (const auto& driver : value) {
        auto& drivers = config["drivers"];
        // The example's driver replaces the base's of the same id.
        drivers.erase(std::remove_if(drivers.begin(), drivers.end(), [&](const json& d) { return d["id"] == driver["id"]; }),
                      drivers.end());
        drivers.push_back(driver);
      }
    } else if (key == "runtime") {
      for (const auto& [name, settings] : value["capabilities"].items()) {
        config["runtime"]["capabilities"][name] = settings;
        auto& list = config["rcan_protocol"]["capabilities"];
        if (std::find(list.begin(), list.end(), name) == list.end()) list.push_back(name);
      }
    } else {
      config[key] = value;  // a top-level block a capability reads (camera): that capability is listed
      auto& list = config["rcan_protocol"]["capabilities"];
      if (std::find(list.begin(), list.end(), id) == list.end()) list.push_back(id);
    }
  }
}

std::vector<std::string> example_blocks(const std::string& id) {
  const auto described = run_tool(rcand_binary(), {"--describe", id, "--plugin-path", plugin_dir().string()});
  REQUIRE(described.exit_code == 0);
  std::vector<std::string> blocks;
  std::istringstream lines(described.out);
  bool in_example = false;
  for (std::string line; std::getline(lines, line);) {
    if (line.starts_with("Example ")) {
      in_example = true;
      blocks.emplace_back();
    } else if (in_example && line.starts_with("    ")) {
      blocks.back() += line.substr(4) + "\n";
    } else {
      in_example = false;
    }
  }
  return blocks;
}

}  // namespace

TEST_CASE("every example rcand --describe prints passes --check-config") {
  std::size_t examples = 0;
  for (const char* id : {"gpio", "pca9685", "pca9685_i2c", "dynamixel", "dynamixel_v2", "sim_diff_drive", "sim_arm",
                         "acme_gripper_sim", "teleop", "nav", "vision", "arm", "chat", "com.acme.gripper", "org.rcand.fleet"}) {
    for (const auto& block : example_blocks(id)) {
      INFO(std::string(id), "\n", block);
      std::vector<rcand::yaml::ConfigDiagnostic> diagnostics;
      const auto parsed = rcand::yaml::yaml_to_json(block, "example", diagnostics);
      REQUIRE(parsed.ok);
      json config = example_base();
      merge_example(config, parsed.doc, id);
      TempDir dir{"rcand-describe-example"};
      dir.write("jwt.secret", kJwtSecret);  // sim_config()'s runtime.auth.jwt_secret_file
      const auto file = dir.write("robot.rcan.yaml", config.dump(2));
      const auto checked = check(file);
      INFO(checked.out, checked.err);
      CHECK(checked.exit_code == 0);
      ++examples;
    }
  }
  CHECK(examples >= 25);
}

TEST_CASE("rcand --describe prints the settings table, what they claim, and names what it knows when asked for something else") {
  const auto gpio = run_tool(rcand_binary(), {"--describe", "gpio", "--plugin-path", plugin_dir().string()});
  INFO(gpio.out, gpio.err);
  CHECK(gpio.exit_code == 0);
  for (const char* text : {"driver gpio (plugin org.rcand.gpio_motor 0.1.0)", "SETTING", "TYPE", "DEFAULT", "RANGE", "REQUIRED",
                           "channels.left", "motor (below)", "in1", "Claims a GPIO line",
                           "Example 1 (passes rcand --check-config):", "    drivers:", "      protocol: gpio"})
    CHECK_MESSAGE(gpio.out.find(text) != std::string::npos, text);
  const auto unknown = run_tool(rcand_binary(), {"--describe", "roboclaw", "--plugin-path", plugin_dir().string()});
  CHECK(unknown.exit_code == 2);
  CHECK(unknown.err.find("--describe: no installed plugin provides 'roboclaw' (known: ") != std::string::npos);
  CHECK(unknown.err.find("dynamixel") != std::string::npos);
}

TEST_CASE("every setting of every bundled manifest has a description and an example or a default") {
  const auto reference = run_tool(rcand_binary(), {"--describe", "--markdown", "--plugin-path", plugin_dir().string()});
  REQUIRE(reference.exit_code == 0);
  std::istringstream lines(reference.out);
  std::size_t settings = 0;
  std::vector<std::string> lacking;
  for (std::string line; std::getline(lines, line);) {
    if (!line.starts_with("| `")) continue;
    std::vector<std::string> cells{""};  // | Setting | Type | Default | Example | Range | Required | Description |
    for (std::size_t i = 1; i + 1 < line.size(); ++i) {
      if (line[i] == '\\' && line[i + 1] == '|') cells.back() += line[++i];
      else if (line[i] == '|') cells.emplace_back();
      else cells.back() += line[i];
    }
    REQUIRE(cells.size() == 7);
    for (auto& cell : cells) {
      cell.erase(0, std::min(cell.size(), cell.find_first_not_of(' ')));
      cell.erase(cell.find_last_not_of(' ') + 1);
    }
    if (cells[0].find(" as ") != std::string::npos) continue;  // "channels.left as Motor": a form's heading, no setting
    ++settings;
    if (cells[6].empty() || (cells[2].empty() && cells[3].empty())) lacking.push_back(cells[0]);
  }
  std::string names;
  for (const auto& name : lacking) names += name + " ";
  INFO("lacking a description, or both an example and a default: ", names);
  CHECK(lacking.empty());
  CHECK(settings >= 120);
}
