// manifests/gpio.json and GpioMotorSettings::from agree: every example the manifest gives is taken by the parser, and
// every setting the parser refuses is refused by the manifest (so rcand --check-config names it before a start).
#include <doctest/doctest.h>

#include "gpio_settings.hpp"
#include "manifest_settings.hpp"

using nlohmann::json;
using rcand::plugins::gpio_motor::GpioMotorSettings;

namespace {

std::string gpio_parser_refusal(const json& settings) {
  try {
    (void)GpioMotorSettings::from(rcand::sdk::ConfigView(settings));
  } catch (const rcand::sdk::ConfigError& e) {
    return e.what();
  }
  return "";
}

json gpio_motors(json left, json right) { return {{"channels", {{"left", std::move(left)}, {"right", std::move(right)}}}}; }

const json kGpioLeft = {{"in1", 17}, {"in2", 27}, {"enable", 22}};
const json kGpioRight = {{"in1", 23}, {"in2", 24}, {"enable", 25}};

}  // namespace

TEST_CASE("gpio: every example in the manifest is taken by the manifest and by the driver's parser") {
  const json manifest = rcand::test::source_manifest("manifests/gpio.json");
  const auto examples = rcand::test::manifest_examples(manifest, "gpio");
  CHECK(examples.size() >= 2);
  for (const auto& example : examples) {
    INFO(example.dump());
    const auto verdict = rcand::test::manifest_verdict(manifest, "gpio", example);
    CHECK(verdict.refusals.empty());
    CHECK(gpio_parser_refusal(verdict.settings) == "");
  }
}

TEST_CASE("gpio: what the driver's parser refuses, the manifest refuses, at the same setting") {
  const json manifest = rcand::test::source_manifest("manifests/gpio.json");
  struct Case {
    json settings;
    std::string key;  // the setting both name
  };
  const std::vector<Case> cases{
      {json::object(), "channels"},
      {{{"channels", {{"left", kGpioLeft}}}}, "channels.right"},
      {gpio_motors({{"in1", 17}}, kGpioRight), "channels.left.in2"},
      {gpio_motors({{"in1", 17}, {"in2", 1024}}, kGpioRight), "channels.left.in2"},
      {gpio_motors({{"in1", 17}, {"in2", ""}}, kGpioRight), "channels.left.in2"},
      {gpio_motors({{"in1", 17}, {"in2", true}}, kGpioRight), "channels.left.in2"},
      {gpio_motors({{"in1", 17}, {"in2", {{"active_low", true}}}}, kGpioRight), "channels.left.in2.line"},
      {gpio_motors({{"in1", 17}, {"in2", {{"line", 27}, {"active_low", "yes"}}}}, kGpioRight), "channels.left.in2.active_low"},
      {gpio_motors({{"in1", 17}, {"in2", 27}, {"pwm", {{"channel", 300}}}}, kGpioRight), "channels.left.pwm.channel"},
      {gpio_motors({{"in1", 17}, {"in2", 27}, {"pwm", {{"frequency_hz", 0}}}}, kGpioRight), "channels.left.pwm.frequency_hz"},
      {gpio_motors({{"in1", 17}, {"in2", 27}, {"pwm", 3}}, kGpioRight), "channels.left.pwm"},
      {gpio_motors({{"in1", 17}, {"in2", 27}, {"reverse", "yes"}}, kGpioRight), "channels.left.reverse"},
      {gpio_motors(kGpioLeft, {{"in1", 23}, {"in2", 17}}), "channels.right.in2"},  // a line used twice
      {{{"chip", ""}, {"channels", gpio_motors(kGpioLeft, kGpioRight)["channels"]}}, "chip"},
      {{{"chip", -1}, {"channels", gpio_motors(kGpioLeft, kGpioRight)["channels"]}}, "chip"},
      {{{"channels", "left"}}, "channels"},
  };
  for (const auto& c : cases) {
    INFO(c.settings.dump());
    const std::string parser = gpio_parser_refusal(c.settings);
    CHECK(parser.find(c.key) != std::string::npos);
    const auto verdict = rcand::test::manifest_verdict(manifest, "gpio", c.settings);
    REQUIRE(!verdict.refusals.empty());
    CHECK(verdict.refusals.front().starts_with(c.key));
  }
}

TEST_CASE("gpio: the manifest also refuses what the parser would silently ignore (a misspelt input moves nothing)") {
  const json manifest = rcand::test::source_manifest("manifests/gpio.json");
  for (const auto& [settings, refusal] : std::vector<std::pair<json, std::string>>{
           {gpio_motors({{"in1", 17}, {"in2", 27}, {"en", 22}}, kGpioRight),
            "channels.left.en: unknown key; expected one of: enable, in1, in2, pwm, reverse; did you mean 'enable'?"},
           {{{"port", "/dev/gpiochip0"}, {"channels", gpio_motors(kGpioLeft, kGpioRight)["channels"]}},
            "port: unknown key; expected one of: channels, chip"},
           {gpio_motors(kGpioLeft, {{"in1", 23}, {"in2", 24}, {"enable", {{"line", 25}, {"activelow", true}}}}),
            "channels.right.enable.activelow: unknown key"},
       }) {
    const std::string settings_text = settings.dump();  // clang 14: a lambda (INFO) cannot capture a structured binding
    INFO(settings_text);
    CHECK(gpio_parser_refusal(settings) == "");  // the parser alone would start with it
    const auto verdict = rcand::test::manifest_verdict(manifest, "gpio", settings);
    REQUIRE(!verdict.refusals.empty());
    CHECK(verdict.refusals.front().starts_with(refusal));
  }
}
