// manifests/feetech.json and FeetechSettings::from agree: every example the manifest gives is taken by both, and
// what the parser refuses the manifest refuses at the same setting. Also the SO-ARM presets' field names.
#include <doctest/doctest.h>

#include "manifest_settings.hpp"
#include "settings.hpp"

using nlohmann::json;
using rcand::plugins::feetech::FeetechSettings;

namespace {

std::string feetech_parser_refusal(const json& settings, const json& robot = json::object()) {
  try {
    (void)FeetechSettings::from(rcand::sdk::ConfigView(settings), rcand::sdk::ConfigView(robot));
  } catch (const rcand::sdk::ConfigError& e) {
    return e.what();
  }
  return "";
}

json feetech_with(json extra, json servos = json::array({{{"id", 1}, {"joint", "shoulder"}}})) {
  if (extra.is_null()) extra = json::object();
  extra["port"] = extra.value("port", "/dev/ttyACM0");
  extra["servos"] = std::move(servos);
  return extra;
}

}  // namespace

TEST_CASE("feetech: every example in the manifest is taken by the manifest and by the driver's parser") {
  const json manifest = rcand::test::source_manifest("manifests/feetech.json");
  const auto examples = rcand::test::manifest_examples(manifest, "feetech");
  CHECK(examples.size() >= 2);
  for (const auto& example : examples) {
    INFO(example.dump());
    const auto verdict = rcand::test::manifest_verdict(manifest, "feetech", example);
    CHECK(verdict.refusals.empty());
    CHECK(feetech_parser_refusal(verdict.settings) == "");
  }
}

TEST_CASE("feetech: what the driver's parser refuses, the manifest refuses, at the same setting") {
  const json manifest = rcand::test::source_manifest("manifests/feetech.json");
  const std::vector<std::pair<json, std::string>> cases{
      {{{"servos", {{{"id", 1}, {"joint", "a"}}}}}, "port"},
      {feetech_with({{"port", ""}}), "port"},
      {feetech_with({}, json::array()), "servos"},
      {feetech_with({{"baud_rate", 57601}}), "baud_rate"},
      {feetech_with({{"model", "scs0009"}}), "model"},
      {feetech_with({}, {{{"id", 254}, {"joint", "a"}}}), "servos[0].id"},
      {feetech_with({}, {{{"id", 1}}}), "servos[0]"},
      {feetech_with({}, {{{"id", 1}, {"joint", "a"}, {"wheel", "left"}}}), "servos[0]"},
      {feetech_with({}, {{{"id", 1}, {"joint", "a"}, {"min_deg", 90}, {"max_deg", -90}}}), "servos[0]"},
      {feetech_with({}, {{{"id", 1}, {"joint", "a"}, {"torque_limit_pct", 120}}}), "servos[0].torque_limit_pct"},
      {feetech_with({}, {{{"id", 1}, {"joint", "a"}, {"max_velocity_dps", 0}}}), "servos[0].max_velocity_dps"},
      {feetech_with({}, {{{"id", 1}, {"joint", "a"}, {"model", "xl430"}}}), "servos[0].model"},
      {feetech_with({}, {{{"id", 1}, {"joint", "a"}}, {{"id", 1}, {"joint", "b"}}}), "servos[1].id"},
      {feetech_with({}, {{{"id", 1}, {"wheel", "left"}}}), "servos"},
      {feetech_with({}, {{{"id", 1}, {"wheel", "left"}, {"invert", "yes"}}, {{"id", 2}, {"wheel", "right"}}}),
       "servos[0].invert"},
      {feetech_with({{"poll_hz", 0.5}}), "poll_hz"},
      {feetech_with({{"retries", 11}}), "retries"},
      {feetech_with({{"lost_after_polls", 0}}), "lost_after_polls"},
      {feetech_with({{"halt_deadline_ms", 101}}), "halt_deadline_ms"},
      {feetech_with({{"joint_velocity_dps", 0}}), "joint_velocity_dps"},
      {feetech_with({{"wheel_max_rpm", -1}}), "wheel_max_rpm"},
  };
  for (const auto& [settings, key] : cases) {
    const std::string settings_text = settings.dump();  // clang 14: a lambda (INFO) cannot capture a structured binding
    INFO(settings_text);
    CHECK(feetech_parser_refusal(settings).find(key) != std::string::npos);
    const auto verdict = rcand::test::manifest_verdict(manifest, "feetech", settings);
    REQUIRE(!verdict.refusals.empty());
    CHECK(verdict.refusals.front().starts_with(key));
  }
}

TEST_CASE("feetech: joint limits from physics.kinematics, in rcand's shape and in the OpenCastor presets' limits_deg") {
  const json robot{
      {"physics",
       {{"kinematics", {{{"joint", "a"}, {"min_deg", -45}, {"max_deg", 45}}, {{"id", "gripper"}, {"limits_deg", {0, 90}}}}}}}};
  const auto settings =
      FeetechSettings::from(rcand::sdk::ConfigView(feetech_with(
                                {{"model", "STS3215"}}, {{{"id", 1}, {"joint", "a"}}, {{"id", 6}, {"joint", "gripper"}}})),
                            rcand::sdk::ConfigView(robot));
  REQUIRE(settings.servos.size() == 2);
  CHECK(settings.servos[0].min_deg == -45);
  CHECK(settings.servos[1].min_deg == 0);
  CHECK(settings.servos[1].max_deg == 90);
  CHECK(settings.servos[1].model == "sts3215");  // the bus-wide model, case as the presets write it
  CHECK(settings.baud_rate == 1000000);
}
