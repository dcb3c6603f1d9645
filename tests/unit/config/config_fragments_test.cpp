// conf.d/ fragments over the robot's config (libs/config/config_fragments.hpp): merged in name order as JSON Merge
// Patches, validated as one document, each key's errors at the fragment's own file:line:column.
#include <doctest/doctest.h>

#include "config_test_support.hpp"
#include "libs/config/config_fragments.hpp"

using namespace config_test;
using rcand::config::ConfigError;
using rcand::config::load_robot_config;

namespace {

std::string robot_file() {
  auto lines = minimal_lines();
  lines.insert(lines.end(), {"rcan_protocol:", "  capabilities: [status, chat]", "agent:", "  provider: grammar",
                             "runtime:", "  logging:", "    level: debug"});
  return join(lines);
}

}  // namespace

TEST_CASE("conf.d: fragments merge over the file in name order; mappings merge, lists and scalars replace") {
  TempDir dir("rcand-confd");
  const auto file = dir.write("robot.rcan.yaml", robot_file());
  CHECK(load_robot_config(file).config.fragment_files.empty());  // no conf.d: the file alone

  dir.write("conf.d/50-site.yaml", "runtime:\n  logging:\n    level: warn\n");
  dir.write("conf.d/10-package.yaml", "runtime:\n  logging:\n    level: error\nrcan_protocol:\n  capabilities: [status]\n");
  for (const char* skipped : {"conf.d/90-old.yaml.dpkg-old", "conf.d/.hidden.yaml", "conf.d/README"})
    dir.write(skipped, "runtime: [not, read]\n");
  const auto loaded = load_robot_config(file);
  REQUIRE(loaded.config.fragment_files.size() == 2);
  CHECK(loaded.config.fragment_files[0].filename() == "10-package.yaml");
  CHECK(loaded.config.fragment_files[1].filename() == "50-site.yaml");
  CHECK(loaded.config.runtime.log_level == "warn");                         // the later fragment wins
  CHECK(loaded.config.capabilities == std::vector<std::string>{"status"});  // a list is replaced whole
  CHECK(loaded.config.robot_name == "rover-1");                             // the rest of the file stays
  CHECK(loaded.config.doc["agent"]["provider"] == "grammar");
}

TEST_CASE("conf.d: null removes a key, so the default applies again") {
  TempDir dir("rcand-confd");
  const auto file = dir.write("robot.rcan.yaml", robot_file());
  dir.write("conf.d/20-default-logging.yaml", "runtime:\n  logging:\n    level: null\n");
  CHECK(load_robot_config(file).config.runtime.log_level == "info");
}

TEST_CASE("conf.d: an error a fragment makes is reported at the fragment's file, line and column") {
  TempDir dir("rcand-confd");
  const auto file = dir.write("robot.rcan.yaml", robot_file());
  const auto fragment = dir.write("conf.d/30-typo.yaml", "# site settings\nruntime:\n  loging:\n    level: warn\n");
  try {
    load_robot_config(file);
    FAIL("a near-miss key in a fragment must be refused");
  } catch (const ConfigError& e) {
    INFO(e.what());
    const auto errors = errors_only(e.diagnostics());
    REQUIRE_FALSE(errors.empty());
    const auto& first = errors[0];
    CHECK(first.mark.file == fragment.string());
    CHECK(first.mark.line == 3);
    CHECK(first.mark.column == 3);
    CHECK(first.message.find("did you mean 'logging'?") != std::string::npos);
  }
}

TEST_CASE("conf.d: a fragment that is not a mapping, or not YAML, is an error naming it") {
  TempDir dir("rcand-confd");
  const auto file = dir.write("robot.rcan.yaml", robot_file());
  const auto list = dir.write("conf.d/10-list.yaml", "- runtime\n- logging\n");
  try {
    load_robot_config(file);
    FAIL("a list fragment must be refused");
  } catch (const ConfigError& e) {
    INFO(e.what());
    const auto errors = errors_only(e.diagnostics());
    REQUIRE(errors.size() == 1);
    CHECK(errors[0].mark.file == list.string());
    CHECK(errors[0].message.find("must be a mapping") != std::string::npos);
  }
  std::filesystem::remove(list);
  const auto broken = dir.write("conf.d/10-broken.yaml", "runtime: [unclosed\n");
  try {
    load_robot_config(file);
    FAIL("a fragment with a syntax error must be refused");
  } catch (const ConfigError& e) {
    CHECK(errors_only(e.diagnostics()).at(0).mark.file == broken.string());
  }
  std::filesystem::remove(broken);
  dir.write("conf.d/10-empty.yaml", "");  // an empty or comment-only fragment changes nothing
  dir.write("conf.d/20-comments.yaml", "# runtime:\n#   logging: {level: warn}\n");
  CHECK(load_robot_config(file).config.runtime.log_level == "debug");
}

TEST_CASE("conf.d merge: a replaced or removed key takes its marks along") {
  std::vector<rcand::config::ConfigDiagnostic> diagnostics;
  auto base = rcand::yaml::yaml_to_json("a:\n  b: [1, 2]\n  c: 3\n", "base.yaml", diagnostics);
  const auto patch = rcand::yaml::yaml_to_json("a:\n  b: 7\n  c: null\n  d:\n    e: null\n    f: 1\n", "patch.yaml", diagnostics);
  REQUIRE(diagnostics.empty());
  rcand::config::merge_config_fragment(base, patch, "patch.yaml", diagnostics);
  CHECK(base.doc == nlohmann::json{{"a", {{"b", 7}, {"d", {{"f", 1}}}}}});  // RFC 7396: nulls never land
  CHECK(base.marks.at("a").file == "base.yaml");                            // a merged mapping keeps its place
  CHECK(base.marks.at("a.b").file == "patch.yaml");
  CHECK(base.marks.count("a.b[0]") == 0);
  CHECK(base.marks.count("a.c") == 0);
  CHECK(base.marks.at("a.d.f").file == "patch.yaml");
}

// Found by fuzz_conf_d: a main file that is a list left its items' marks ("[0]") after the merge replaced it by {}.
TEST_CASE("conf.d merge: a fragment over a main file that is not a mapping leaves no marks of the old items") {
  std::vector<rcand::config::ConfigDiagnostic> diagnostics;
  auto base = rcand::yaml::yaml_to_json("- 1\n- {a: 2}\n", "base.yaml", diagnostics);
  const auto patch = rcand::yaml::yaml_to_json("b: 3\n", "patch.yaml", diagnostics);
  REQUIRE(diagnostics.empty());
  REQUIRE(base.marks.count("[1].a") == 1);
  rcand::config::merge_config_fragment(base, patch, "patch.yaml", diagnostics);
  CHECK(base.doc == nlohmann::json{{"b", 3}});
  CHECK(base.marks.count("[0]") == 0);
  CHECK(base.marks.count("[1]") == 0);
  CHECK(base.marks.count("[1].a") == 0);
  CHECK(base.marks.at("b").file == "patch.yaml");
}
