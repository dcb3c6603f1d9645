// Issue 30 item 4: the reference runtime's driver shapes for hardware rcand's plugins drive, read as those plugins'
// settings (libs/config/foreign_shapes.hpp), each reading one warning.
#include <doctest/doctest.h>

#include <algorithm>

#include "config_test_support.hpp"

using namespace config_test;
using nlohmann::json;

namespace {

bool foreign_shape_has(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

// The minimal file with `extra` lines after it.
rcand::config::LoadedConfig parse_with(std::initializer_list<std::string> extra) {
  auto lines = minimal_lines();
  lines.insert(lines.end(), extra);
  return parse_ok(join(lines));
}

std::size_t warnings_naming(const rcand::config::LoadedConfig& loaded, const std::string& part) {
  return static_cast<std::size_t>(std::count_if(loaded.warnings.begin(), loaded.warnings.end(), [&part](const auto& warning) {
    return foreign_shape_has(warning.message, part);
  }));
}

}  // namespace

TEST_CASE("pca9685: one channel per wheel is one H-bridge per side, front input in1, frequency pwm_frequency_hz") {
  const auto loaded =
      parse_with({"drivers:", "  - id: motor_driver", "    protocol: pca9685_i2c", "    address: '0x40'", "    frequency: 50",
                  "    channels: {left_front: 0, left_rear: 1, right_front: 2, right_rear: 3}"});
  const json& settings = loaded.config.drivers.at(0).settings;
  CHECK(settings["channels"] == json::parse(R"({"left": {"in1": 0, "in2": 1}, "right": {"in1": 2, "in2": 3}})"));
  CHECK(settings["pwm_frequency_hz"] == 50);
  CHECK_FALSE(settings.contains("frequency"));
  CHECK(warnings_naming(loaded, "one channel per wheel") == 1);
}

TEST_CASE("pca9685: per-wheel names in either order; polarity -1 on both wheels of a side reverses that motor") {
  const auto loaded = parse_with({"drivers:", "  - id: motor_driver", "    protocol: pca9685_i2c",
                                  "    channels: {rear_left: 2, front_left: 0, front_right: 1, rear_right: 3}",
                                  "    polarity: {front_left: 1, front_right: -1, rear_left: 1, rear_right: -1}"});
  const json& settings = loaded.config.drivers.at(0).settings;
  CHECK(settings["channels"] == json::parse(R"({"left": {"in1": 0, "in2": 2}, "right": {"in1": 1, "in2": 3, "reverse": true}})"));
  CHECK_FALSE(settings.contains("polarity"));
}

TEST_CASE("pca9685: wheels of one side with different polarity are no one motor: left as written, with the reason") {
  const auto loaded = parse_with({"drivers:", "  - id: motor_driver", "    protocol: pca9685_i2c",
                                  "    channels: {front_left: 0, front_right: 1, rear_left: 2, rear_right: 3}",
                                  "    polarity: {front_left: 1, rear_left: -1}"});
  CHECK(loaded.config.drivers.at(0).settings["channels"].contains("front_left"));  // the plugin's schema refuses it
  CHECK(warnings_naming(loaded, "polarity of front_left and rear_left differ") == 1);
}

TEST_CASE("pca9685: servo channels of a board another entry drives are ignored with one warning, not a claim conflict") {
  const auto loaded =
      parse_with({"drivers:", "  - id: motor_driver", "    protocol: pca9685_i2c", "    port: /dev/i2c-1", "    address: '0x40'",
                  "    channels: {left_front: 0, left_rear: 1, right_front: 2, right_rear: 3}", "  - id: servo_camera_pan",
                  "    protocol: pca9685_i2c", "    port: /dev/i2c-1", "    address: 64", "    channels: {pan: 8, tilt: 9}",
                  "    servo_range_deg: 180"});
  REQUIRE(loaded.config.drivers.size() == 1);
  CHECK(loaded.config.drivers[0].id == "motor_driver");
  CHECK(warnings_naming(loaded,
                        "channels {\"pan\":8,\"tilt\":9} (servos) are other channels of the PCA9685 at 0x40 on "
                        "/dev/i2c-1 that drivers[0] ('motor_driver') drives") == 1);
  // On a board of its own it is no shared board: left as written for the plugin to refuse.
  const auto alone =
      parse_with({"drivers:", "  - id: pan", "    protocol: pca9685_i2c", "    address: 65", "    channels: {pan: 8, tilt: 9}"});
  CHECK(alone.config.drivers.size() == 1);
}

TEST_CASE("arduino_serial_json: pins in the reference runtime's own shapes are the firmware's, ignored with one warning") {
  const auto loaded =
      parse_with({"drivers:", "  - id: motor_driver", "    protocol: arduino_serial_json", "    port: /dev/ttyUSB0",
                  "    channels: {fl_pwm: 5, fl_dir: 4, fr_pwm: 6, fr_dir: 7}", "    motor_driver_ic: TB6612FNG",
                  "    left_pwm_pin: 5", "    left_in1: 7", "    max_pwm: 200"});
  const json& settings = loaded.config.drivers.at(0).settings;
  CHECK_FALSE(settings.contains("channels"));
  CHECK_FALSE(settings.contains("left_pwm_pin"));
  CHECK_FALSE(settings.contains("left_in1"));
  CHECK_FALSE(settings.contains("motor_driver_ic"));
  CHECK(settings["max_pwm"] == 200);  // the driver's own setting stays
  CHECK(warnings_naming(loaded, "are fixed by the bridge firmware") == 1);
  // rcand's own `channels` names (its record of the wiring) stay as written, without a warning.
  const auto own = parse_with({"drivers:", "  - id: motor_driver", "    protocol: arduino_serial_json", "    port: /dev/ttyUSB0",
                               "    channels: {left_pwm_pin: 5, right_pwm_pin: 10}"});
  CHECK(own.config.drivers.at(0).settings["channels"]["left_pwm_pin"] == 5);
  CHECK(warnings_naming(own, "are fixed by the bridge firmware") == 0);
}

TEST_CASE("gpio entries that are no H-bridge: the Robot HAT and an HC-SR04 as their protocols, other sensors ignored") {
  const auto loaded =
      parse_with({"drivers:", "  - {id: motor_driver, protocol: gpio, interface: i2c, address: '0x14', left_motor_channel: 0}",
                  "  - {id: ultrasonic_sensor, protocol: gpio, sensor_type: hcsr04, trigger_gpio: 27, echo_gpio: 22}",
                  "  - {id: buzzer, protocol: gpio, sensor_type: buzzer, gpio: 4}",
                  "  - {id: wheels, protocol: gpio, channels: {left: {in1: 5, in2: 6}, right: {in1: 20, in2: 21}}}"});
  const auto& drivers = loaded.config.drivers;
  REQUIRE(drivers.size() == 3);
  CHECK(drivers[0].protocol == "sunfounder_robot_hat");
  CHECK(drivers[1].protocol == "gpio_hcsr04");
  CHECK(drivers[2].id == "wheels");
  CHECK(drivers[2].protocol == "gpio");
  CHECK(warnings_naming(loaded, "is the SunFounder Robot HAT's motor and servo controller") == 1);
  CHECK(warnings_naming(loaded, "is an HC-SR04 on GPIO lines") == 1);
  CHECK(warnings_naming(loaded, "('buzzer') (protocol 'gpio', sensor_type \"buzzer\") is a sensor or output") == 1);
}

TEST_CASE("camera.type oakd: a driver of protocol 'oakd' (no plugin provides it), not the vision plugin's camera") {
  const auto loaded = parse_with({"camera:", "  type: oakd", "  resolution: [1280, 720]"});
  CHECK_FALSE(loaded.config.has_camera);
  REQUIRE(loaded.config.drivers.size() == 1);
  CHECK(loaded.config.drivers[0].protocol == "oakd");
  CHECK(loaded.config.drivers[0].id == "camera");
  CHECK(warnings_naming(loaded, "camera.type 'oakd' (a Luxonis OAK camera") == 1);
}

TEST_CASE("teleop listed for an arm (the reference runtime's leader/follower) is taken out with one warning") {
  const auto arm = parse_with({"rcan_protocol:", "  capabilities: [status, arm, teleop, chat]", "physics:", "  type: arm"});
  CHECK(arm.config.capabilities == std::vector<std::string>{"status", "arm", "chat"});
  CHECK(warnings_naming(arm, "rcan_protocol.capabilities[2]: teleop on an arm") == 1);
  // A base keeps it: teleop is its driving.
  const auto base = parse_with({"rcan_protocol:", "  capabilities: [status, teleop]", "physics:", "  type: differential"});
  CHECK(base.config.capabilities == std::vector<std::string>{"status", "teleop"});
}

TEST_CASE("gpio: a TB6612 as {ain1_gpio, ..., standby_gpio} is motor A left, B right, PWM inputs as enables") {
  const auto loaded = parse_with({"drivers:", "  - id: motor_driver", "    protocol: gpio",
                                  "    channels: {ain1_gpio: 13, ain2_gpio: 6, pwma_gpio: 12, bin1_gpio: 21, bin2_gpio: 20, "
                                  "pwmb_gpio: 26, standby_gpio: 19}",
                                  "    pwm_freq_hz: 500"});
  const json& settings = loaded.config.drivers.at(0).settings;
  CHECK(settings["channels"] == json::parse(R"({"left": {"in1": 13, "in2": 6, "enable": 12},
                                                "right": {"in1": 21, "in2": 20, "enable": 26}})"));
  CHECK(settings["standby"] == 19);
  CHECK_FALSE(settings.contains("pwm_freq_hz"));
  CHECK(warnings_naming(loaded, "(a TB6612 on GPIO lines, the reference runtime's shape)") == 1);
  // A key of its own in that block: left as written, for the plugin to name.
  const auto other = parse_with({"drivers:", "  - id: motor_driver", "    protocol: gpio",
                                 "    channels: {ain1_gpio: 13, ain2_gpio: 6, bin1_gpio: 21, bin2_gpio: 20, led_gpio: 4}"});
  CHECK(other.config.drivers.at(0).settings["channels"].contains("ain1_gpio"));
}
