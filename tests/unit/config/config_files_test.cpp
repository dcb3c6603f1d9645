// load_robot_config(): reading from disk, resolving relative paths, and the bundled sim config.
#include "config_test_support.hpp"

#include <doctest/doctest.h>

using namespace config_test;
using rcand::config::ConfigError;
using rcand::config::load_robot_config;
namespace fs = std::filesystem;

TEST_CASE("relative plugin_paths, jwt_secret_file and swarm_file resolve against the file's folder") {
  TempDir dir;
  auto lines = minimal_lines();
  lines.push_back("runtime:");
  lines.push_back("  plugin_paths: [plugins, ./more/../extra, /abs/plugins]");
  lines.push_back("  auth: {jwt_secret_file: keys/jwt.secret}");
  lines.push_back("  swarm_file: swarm.yaml");
  const fs::path file = dir.write("robots/rover/rover.rcan.yaml", join(lines));
  const fs::path folder = dir.path() / "robots" / "rover";

  const auto c = load_robot_config(file).config;
  CHECK(c.source_file == file);
  CHECK(c.source_file.is_absolute());
  REQUIRE(c.runtime.plugin_paths.size() == 3);
  CHECK(c.runtime.plugin_paths[0] == folder / "plugins");
  CHECK(c.runtime.plugin_paths[1] == folder / "extra");
  CHECK(c.runtime.plugin_paths[2] == "/abs/plugins");
  CHECK(*c.runtime.auth.jwt_secret_file == folder / "keys" / "jwt.secret");
  CHECK(c.runtime.swarm_file == folder / "swarm.yaml");
  CHECK(c.marks.at("runtime.plugin_paths").file == file.string());  // marks name the file as it was given
}

TEST_CASE("errors from a file carry its name") {
  TempDir dir;
  auto lines = minimal_lines();
  lines[2] = "  robot_name: 42";
  const fs::path file = dir.write("bad.rcan.yaml", join(lines));
  try {
    load_robot_config(file);
    FAIL("expected a ConfigError");
  } catch (const ConfigError& e) {
    REQUIRE(e.diagnostics().size() == 1);
    CHECK(std::string(e.what()).rfind(file.string() + ":3:3: error: metadata.robot_name: expected a string", 0) == 0);
  }
}

TEST_CASE("a file that does not exist is one error with line 0") {
  TempDir dir;
  const fs::path missing = dir.path() / "nope.rcan.yaml";
  try {
    load_robot_config(missing);
    FAIL("expected a ConfigError");
  } catch (const ConfigError& e) {
    REQUIRE(e.diagnostics().size() == 1);
    const auto& d = e.diagnostics()[0];
    CHECK(d.mark.line == 0);
    CHECK(d.mark.file == missing.string());
    CHECK(d.format() == missing.string() + ": error: cannot read the config file: no such file");
  }
}

TEST_CASE("a directory or an empty file is one clear error") {
  TempDir dir;
  try {
    load_robot_config(dir.path());
    FAIL("expected a ConfigError");
  } catch (const ConfigError& e) {
    REQUIRE(e.diagnostics().size() == 1);
    CHECK(std::string(e.what()).find("is a directory") != std::string::npos);
  }
  const fs::path empty = dir.write("empty.rcan.yaml", "");
  try {
    load_robot_config(empty);
    FAIL("expected a ConfigError");
  } catch (const ConfigError& e) {
    REQUIRE(e.diagnostics().size() == 1);
    CHECK(e.diagnostics()[0].format().rfind(empty.string() + ":1:1: error: the file is empty", 0) == 0);
  }
}

TEST_CASE("the bundled simulated robot config loads cleanly (when present)") {
  const fs::path sim = fs::path(RCAND_SOURCE_DIR) / "config" / "sim-rover.rcan.yaml";
  if (!fs::exists(sim)) {
    MESSAGE("skipped: " << sim.string() << " does not exist yet");
    return;
  }
  try {
    const auto loaded = load_robot_config(sim);
    for (const auto& w : loaded.warnings) MESSAGE(w.format());
    CHECK(loaded.warnings.empty());
    CHECK_FALSE(loaded.config.robot_name.empty());
    CHECK_FALSE(loaded.config.drivers.empty());
  } catch (const ConfigError& e) {
    FAIL("config/sim-rover.rcan.yaml does not load:\n" << std::string(e.what()));
  }
}
