// rcand's own configs (the bundled simulated robot, the packaged default) pass the RCAN reference SDK's config
// validation as its documentation states it (the SDK itself cannot be fetched here): the required top-level blocks,
// a non-empty metadata.robot_name and agent.model, at least one driver. They also load with no warning at all, so
// they pass `rcand --strict`.
#include "config_test_support.hpp"

#include <doctest/doctest.h>

#include <array>

using rcand::config::ConfigError;
using rcand::config::load_robot_config;
using rcand::config::LoadOptions;
namespace fs = std::filesystem;

namespace {

// The reference validator's rules, one problem per line ("" when the document passes).
std::string reference_problems(const nlohmann::json& doc) {
  std::string problems;
  if (!doc.is_object()) return "the document is not a mapping\n";
  for (const char* block : {"rcan_version", "metadata", "agent", "physics", "drivers", "network", "rcan_protocol"})
    if (!doc.contains(block)) problems += std::string("missing required top-level key '") + block + "'\n";
  const auto non_empty_string = [&](const char* block, const char* key) {
    const auto it = doc.find(block);
    if (it == doc.end() || !it->is_object()) return;
    const auto value = it->find(key);
    if (value == it->end() || !value->is_string() || value->get<std::string>().empty())
      problems += std::string("missing or empty required key '") + block + "." + key + "'\n";
  };
  non_empty_string("agent", "model");
  non_empty_string("metadata", "robot_name");
  if (const auto drivers = doc.find("drivers"); drivers != doc.end() && (!drivers->is_array() || drivers->empty()))
    problems += "'drivers' must be a non-empty list\n";
  return problems;
}

}  // namespace

TEST_CASE("the reference rules themselves: what they refuse") {
  auto doc = nlohmann::json::parse(R"({"rcan_version": "1.3", "metadata": {"robot_name": "r"}, "agent": {"model": "m"},
    "physics": {}, "drivers": [{"protocol": "sim"}], "network": {}, "rcan_protocol": {}})");
  CHECK(reference_problems(doc).empty());
  auto no_agent = doc;
  no_agent.erase("agent");
  CHECK(reference_problems(no_agent) == "missing required top-level key 'agent'\n");
  auto empty_model = doc;
  empty_model["agent"]["model"] = "";
  CHECK(reference_problems(empty_model) == "missing or empty required key 'agent.model'\n");
  auto no_drivers = doc;
  no_drivers["drivers"] = nlohmann::json::array();
  CHECK(reference_problems(no_drivers) == "'drivers' must be a non-empty list\n");
}

TEST_CASE("the bundled and packaged configs pass the reference rules and rcand --strict") {
  const fs::path root(RCAND_SOURCE_DIR);
  for (const fs::path& file : {root / "config" / "sim-rover.rcan.yaml", root / "packaging" / "etc" / "robot.rcan.yaml"}) {
    CAPTURE(file.string());
    REQUIRE(fs::exists(file));
    try {
      const auto loaded = load_robot_config(file, LoadOptions{.strict = true});
      CHECK(loaded.warnings.empty());
      CHECK(reference_problems(loaded.config.doc) == "");
      CHECK(loaded.config.has_agent);
    } catch (const ConfigError& e) {
      FAIL(file.string() << " is refused with --strict:\n" << std::string(e.what()));
    }
  }
}
