// manifests/dynamixel.json and DynamixelSettings::from agree: every example the manifest gives is taken by the
// parser, and every setting the parser refuses is refused by the manifest (so rcand --check-config names it first).
#include <doctest/doctest.h>

#include "manifest_settings.hpp"
#include "settings.hpp"

using nlohmann::json;
using rcand::plugins::dynamixel::DynamixelSettings;

namespace {

std::string dxl_parser_refusal(const json& settings) {
  try {
    (void)DynamixelSettings::from(rcand::sdk::ConfigView(settings));
  } catch (const rcand::sdk::ConfigError& e) {
    return e.what();
  }
  return "";
}

json dxl_with(json extra, json servos = json::array({{{"id", 1}, {"joint", "shoulder"}}})) {
  if (extra.is_null()) extra = json::object();
  extra["port"] = extra.value("port", "/dev/ttyUSB0");
  extra["servos"] = std::move(servos);
  return extra;
}

}  // namespace

TEST_CASE("dynamixel: every example in the manifest is taken by the manifest and by the driver's parser") {
  const json manifest = rcand::test::source_manifest("manifests/dynamixel.json");
  for (const char* protocol : {"dynamixel", "dynamixel_v2"}) {
    const auto examples = rcand::test::manifest_examples(manifest, protocol);
    CHECK(examples.size() >= 2);
    for (const auto& example : examples) {
      INFO(protocol << " " << example.dump());
      const auto verdict = rcand::test::manifest_verdict(manifest, protocol, example);
      CHECK(verdict.refusals.empty());
      CHECK(dxl_parser_refusal(verdict.settings) == "");
    }
  }
}

TEST_CASE("dynamixel: what the driver's parser refuses, the manifest refuses, at the same setting") {
  const json manifest = rcand::test::source_manifest("manifests/dynamixel.json");
  const std::vector<std::pair<json, std::string>> cases{
      {{{"servos", {{{"id", 1}, {"joint", "a"}}}}}, "port"},
      {dxl_with({{"port", ""}}), "port"},
      {dxl_with({}, json::array()), "servos"},
      {{{"port", "/dev/ttyUSB0"}}, "servos"},
      {dxl_with({{"baud_rate", 1000001}}), "baud_rate"},
      {dxl_with({}, {{{"id", 253}, {"joint", "a"}}}), "servos[0].id"},
      {dxl_with({}, {{{"joint", "a"}}}), "servos[0]"},
      {dxl_with({}, {{{"id", 1}}}), "servos[0]"},
      {dxl_with({}, {{{"id", 1}, {"joint", "a"}, {"wheel", "left"}}}), "servos[0]"},
      {dxl_with({}, {{{"id", 1}, {"joint", ""}}}), "servos[0].joint"},
      {dxl_with({}, {{{"id", 1}, {"wheel", "middle"}}, {{"id", 2}, {"wheel", "right"}}}), "servos[0].wheel"},
      {dxl_with({}, {{{"id", 1}, {"joint", "a"}, {"min_deg", 90}, {"max_deg", -90}}}), "servos[0]"},
      {dxl_with({}, {{{"id", 1}, {"joint", "a"}, {"min_deg", "low"}}}), "servos[0].min_deg"},
      {dxl_with({}, {{{"id", 1}, {"joint", "a"}}, {{"id", 1}, {"joint", "b"}}}), "servos[1].id"},
      {dxl_with({}, {{{"id", 1}, {"joint", "a"}}, {{"id", 2}, {"joint", "a"}}}), "servos[1]"},
      {dxl_with({}, {{{"id", 1}, {"wheel", "left"}}}), "servos"},
      {dxl_with({}, {{{"id", 1}, {"wheel", "left"}, {"reverse", "yes"}}, {{"id", 2}, {"wheel", "right"}}}), "servos[0].reverse"},
      {dxl_with({{"watchdog_ms", 3000}}), "watchdog_ms"},
      {dxl_with({{"watchdog_ms", 20}}), "watchdog_ms"},
      {dxl_with({{"poll_hz", 0.5}}), "poll_hz"},
      {dxl_with({{"reply_timeout_ms", 0}}), "reply_timeout_ms"},
      {dxl_with({{"halt_deadline_ms", 101}}), "halt_deadline_ms"},
      {dxl_with({{"command_timeout_ms", 0}}), "command_timeout_ms"},
      {dxl_with({{"joint_velocity_dps", 0}}), "joint_velocity_dps"},
      {dxl_with({{"wheel_max_rpm", -1}}), "wheel_max_rpm"},
      {dxl_with({{"reboot_on_error", "no"}}), "reboot_on_error"},
  };
  for (const auto& [settings, key] : cases) {
    const std::string settings_text = settings.dump();  // clang 14: a lambda (INFO) cannot capture a structured binding
    INFO(settings_text);
    CHECK(dxl_parser_refusal(settings).find(key) != std::string::npos);
    const auto verdict = rcand::test::manifest_verdict(manifest, "dynamixel", settings);
    REQUIRE(!verdict.refusals.empty());
    CHECK(verdict.refusals.front().starts_with(key));
  }
}

TEST_CASE("dynamixel: the manifest also refuses what the parser would take and ignore") {
  const json manifest = rcand::test::source_manifest("manifests/dynamixel.json");
  for (const auto& [settings, refusal] : std::vector<std::pair<json, std::string>>{
           {dxl_with({{"baudrate", 1000000}}), "baudrate: unknown key; expected one of: baud_rate,"},
           {dxl_with({}, {{{"id", 1}, {"joint", "a"}, {"max_dge", 90}}}), "servos[0].max_dge: unknown key"},
       }) {
    const std::string settings_text = settings.dump();  // clang 14: a lambda (INFO) cannot capture a structured binding
    INFO(settings_text);
    CHECK(dxl_parser_refusal(settings) == "");
    const auto verdict = rcand::test::manifest_verdict(manifest, "dynamixel", settings);
    REQUIRE(!verdict.refusals.empty());
    CHECK(verdict.refusals.front().starts_with(refusal));
  }
}
