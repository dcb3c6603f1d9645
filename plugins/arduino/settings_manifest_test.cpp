// manifests/arduino.json and ArduinoSettings::from agree: every example the manifest gives is taken by the parser,
// and every setting the parser refuses is refused by the manifest (so rcand --check-config names it first).
#include <doctest/doctest.h>

#include "manifest_settings.hpp"
#include "settings.hpp"

using nlohmann::json;
using rcand::plugins::arduino::ArduinoSettings;

namespace {

std::string arduino_parser_refusal(const json& settings) {
  try {
    (void)ArduinoSettings::from(rcand::sdk::ConfigView(settings));
  } catch (const rcand::sdk::ConfigError& e) {
    return e.what();
  }
  return "";
}

json arduino_with(json extra) {
  if (extra.is_null()) extra = json::object();
  extra["port"] = extra.value("port", "/dev/ttyACM0");
  return extra;
}

}  // namespace

TEST_CASE("arduino: every example in the manifest is taken by the manifest and by the driver's parser") {
  const json manifest = rcand::test::source_manifest("manifests/arduino.json");
  const auto examples = rcand::test::manifest_examples(manifest, "arduino_serial_json");
  CHECK(examples.size() >= 2);
  for (const auto& example : examples) {
    const std::string example_text = example.dump();
    INFO(example_text);
    const auto verdict = rcand::test::manifest_verdict(manifest, "arduino_serial_json", example);
    CHECK(verdict.refusals.empty());
    CHECK(arduino_parser_refusal(verdict.settings) == "");
  }
  // The reference runtime's preset entry (config/presets/arduino_l298n.rcan.yaml), field names as written.
  const json preset{{"port", "/dev/ttyACM0"},
                    {"baud", 115200},
                    {"channels",
                     {{"left_pwm_pin", 5},
                      {"left_dir_a", 6},
                      {"left_dir_b", 7},
                      {"right_pwm_pin", 10},
                      {"right_dir_a", 8},
                      {"right_dir_b", 9}}},
                    {"max_pwm", 255},
                    {"deadband_pwm", 40}};
  const auto verdict = rcand::test::manifest_verdict(manifest, "arduino_serial_json", preset);
  CHECK(verdict.refusals.empty());
  const auto parsed = ArduinoSettings::from(rcand::sdk::ConfigView(verdict.settings));
  CHECK(parsed.baud == 115200);
  CHECK(parsed.channels.at("right_pwm_pin") == 10);
  CHECK(parsed.heartbeat.count() == 250);
  CHECK(!parsed.ultrasonic);
}

TEST_CASE("arduino: what the driver's parser refuses, the manifest refuses, at the same setting") {
  const json manifest = rcand::test::source_manifest("manifests/arduino.json");
  const std::vector<std::pair<json, std::string>> cases{
      {json::object(), "port"},
      {arduino_with({{"port", ""}}), "port"},
      {arduino_with({{"baud", 115201}}), "baud"},
      {arduino_with({{"baud_rate", 12345}}), "baud_rate"},
      {arduino_with({{"max_pwm", 0}}), "max_pwm"},
      {arduino_with({{"max_pwm", 256}}), "max_pwm"},
      {arduino_with({{"deadband_pwm", -1}}), "deadband_pwm"},
      {arduino_with({{"max_pwm", 100}, {"deadband_pwm", 120}}), "deadband_pwm"},
      {arduino_with({{"invert_left", "yes"}}), "invert_left"},
      {arduino_with({{"timeout_s", 0.01}}), "timeout_s"},
      {arduino_with({{"heartbeat_ms", 900}}), "heartbeat_ms"},
      {arduino_with({{"halt_deadline_ms", 0}}), "halt_deadline_ms"},
      {arduino_with({{"boot_timeout_ms", 50}}), "boot_timeout_ms"},
      {arduino_with({{"command_timeout_ms", 5}}), "command_timeout_ms"},
      {arduino_with({{"channels", {{"left_pwm_pin", 70}}}}), "channels.left_pwm_pin"},
      {arduino_with({{"ultrasonic", {{"poll_hz", 0}}}}), "ultrasonic.poll_hz"},
      {arduino_with({{"ultrasonic", {{"sensor_type", ""}}}}), "ultrasonic.sensor_type"},
      {arduino_with({{"ultrasonic", {{"no_echo", "ignore"}}}}), "ultrasonic.no_echo"},
      {arduino_with({{"ultrasonic", {{"poll_hz", 2}, {"stale_ms", 500}}}}), "ultrasonic.stale_ms"},
      {arduino_with({{"ultrasonic", {{"echo_pin", -1}}}}), "ultrasonic.echo_pin"},
  };
  for (const auto& [settings, key] : cases) {
    const std::string settings_text = settings.dump();  // clang 14: a lambda (INFO) cannot capture a structured binding
    const std::string key_text = key;
    INFO(settings_text);
    INFO(key_text);
    CHECK(arduino_parser_refusal(settings).find(key_text) != std::string::npos);
    const auto verdict = rcand::test::manifest_verdict(manifest, "arduino_serial_json", settings);
    REQUIRE(!verdict.refusals.empty());
    CHECK(verdict.refusals.front().starts_with(key_text));
  }
}

TEST_CASE("arduino: the manifest refuses what the parser would take and ignore, and both baud names at once") {
  const json manifest = rcand::test::source_manifest("manifests/arduino.json");
  for (const auto& settings : {arduino_with({{"baudrate", 115200}}), arduino_with({{"channels", {{"left_pwm", 5}}}}),
                               arduino_with({{"ultrasonic", {{"trigger", 12}}}})}) {
    const std::string settings_text = settings.dump();
    INFO(settings_text);
    CHECK(arduino_parser_refusal(settings) == "");
    CHECK(!rcand::test::manifest_verdict(manifest, "arduino_serial_json", settings).refusals.empty());
  }
  const json both = arduino_with({{"baud", 115200}, {"baud_rate", 115200}});
  CHECK(arduino_parser_refusal(both).find("baud_rate") != std::string::npos);
  CHECK(!rcand::test::manifest_verdict(manifest, "arduino_serial_json", both).refusals.empty());
}
