// manifests/pca9685.json and Pca9685Settings::from agree: every example the manifest gives is taken by the parser, and
// every setting the parser refuses is refused by the manifest (so rcand --check-config names it before a start).
#include <doctest/doctest.h>

#include "manifest_settings.hpp"
#include "pca9685_drive.hpp"

using nlohmann::json;
using rcand::plugins::pca9685::Pca9685Settings;

namespace {

std::string pca_parser_refusal(const json& settings) {
  try {
    (void)Pca9685Settings::from(rcand::sdk::ConfigView(settings));
  } catch (const rcand::sdk::ConfigError& e) {
    return e.what();
  }
  return "";
}

json pca_with(json extra, json left = {{"esc", 0}}, json right = {{"esc", 1}}) {
  extra["channels"] = {{"left", std::move(left)}, {"right", std::move(right)}};
  return extra;
}

}  // namespace

TEST_CASE("pca9685: every example in the manifest is taken by the manifest and by the driver's parser") {
  const json manifest = rcand::test::source_manifest("manifests/pca9685.json");
  for (const char* protocol : {"pca9685", "pca9685_i2c"}) {
    const auto examples = rcand::test::manifest_examples(manifest, protocol);
    CHECK(examples.size() >= 2);
    for (const auto& example : examples) {
      INFO(protocol << " " << example.dump());
      const auto verdict = rcand::test::manifest_verdict(manifest, protocol, example);
      CHECK(verdict.refusals.empty());
      CHECK(pca_parser_refusal(verdict.settings) == "");
    }
  }
}

TEST_CASE("pca9685: what the driver's parser refuses, the manifest refuses, at the same setting") {
  const json manifest = rcand::test::source_manifest("manifests/pca9685.json");
  const std::vector<std::pair<json, std::string>> cases{
      {json::object(), "channels"},
      {pca_with({}, {{"esc", 16}}), "channels.left.esc"},
      {pca_with({}, {{"esc", -1}}), "channels.left.esc"},
      {pca_with({}, {{"in1", 0}}), "channels.left"},
      {pca_with({}, {{"esc", 0}, {"min_us", 400}}), "channels.left.min_us"},
      {pca_with({}, {{"esc", 0}, {"min_us", 1600}}), "channels.left"},
      {pca_with({}, {{"pwm", 2}, {"in1", 0}, {"in2", 1}}, {{"pwm", 2}, {"in1", 3}, {"in2", 4}}), "channels.right"},
      {pca_with({}, {{"esc", 0}, {"reverse", 1}}), "channels.left.reverse"},
      {pca_with({{"address", 0x80}}), "address"},
      {pca_with({{"address", "0x78"}}), "address"},
      {pca_with({{"address", "forty"}}), "address"},
      {pca_with({{"port", ""}}), "port"},
      {pca_with({{"port", -1}}), "port"},
      {pca_with({{"pwm_frequency_hz", 2000}}), "pwm_frequency_hz"},
      {pca_with({{"pwm_frequency_hz", 1500}, {"oscillator_hz", 20000000}}), "pwm_frequency_hz"},
      {pca_with({{"oscillator_hz", 60000000}}), "oscillator_hz"},
      {pca_with({{"oe_chip", "/dev/gpiochip0"}}), "oe_line"},
      {pca_with({{"oe_line", 2000}}), "oe_line"},
      {pca_with({{"halt_deadline_ms", 0}}), "halt_deadline_ms"},
      {pca_with({{"command_timeout_ms", 5000}}), "command_timeout_ms"},
      {pca_with({{"i2c_timeout_ms", 5}}), "i2c_timeout_ms"},
      {{{"channels", {{"left", {{"esc", 0}}}, {"right", {{"esc", 1}}}, {"middle", {{"esc", 2}}}}}}, "channels.middle"},
  };
  for (const auto& [settings, key] : cases) {
    const std::string settings_text = settings.dump();  // clang 14: a lambda (INFO) cannot capture a structured binding
    INFO(settings_text);
    CHECK(pca_parser_refusal(settings).find(key) != std::string::npos);
    const auto verdict = rcand::test::manifest_verdict(manifest, "pca9685", settings);
    REQUIRE(!verdict.refusals.empty());
    CHECK(verdict.refusals.front().starts_with(key));
  }
}

TEST_CASE("pca9685: the manifest also refuses what the parser would take and ignore") {
  const json manifest = rcand::test::source_manifest("manifests/pca9685.json");
  for (const auto& [settings, refusal] : std::vector<std::pair<json, std::string>>{
           {pca_with({{"frequency", 50}}), "frequency: unknown key"},
           {pca_with({}, {{"in1", 0}, {"in2", 1}, {"min_us", 1000}}, {{"esc", 3}}), "channels.left.min_us: unknown key"},
       }) {
    const std::string settings_text = settings.dump();  // clang 14: a lambda (INFO) cannot capture a structured binding
    INFO(settings_text);
    CHECK(pca_parser_refusal(settings) == "");
    const auto verdict = rcand::test::manifest_verdict(manifest, "pca9685", settings);
    REQUIRE(!verdict.refusals.empty());
    CHECK(verdict.refusals.front().starts_with(refusal));
  }
}
