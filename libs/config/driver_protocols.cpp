#include "libs/config/driver_protocols.hpp"

#include <algorithm>
#include <array>
#include <cctype>

namespace rcand::config {
namespace {

bool same_name(std::string_view a, std::string_view b) noexcept {
  return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) {
           return std::tolower(static_cast<unsigned char>(x)) == std::tolower(static_cast<unsigned char>(y));
         });
}

// Same hardware, another name. Only names whose hardware is exactly what the plugin drives: an L298N on a
// Raspberry Pi's GPIO is the gpio plugin's H-bridge, an L298N behind an Arduino is not (see kUnserved).
constexpr std::array kAliases{
    ProtocolAlias{"l298n", "gpio", "GPIO H-bridges (L298N)"},
    ProtocolAlias{"tb6612", "gpio", "GPIO H-bridges (TB6612)"},
    ProtocolAlias{"tb6612fng", "gpio", "GPIO H-bridges (TB6612FNG)"},
    ProtocolAlias{"gpio_motor", "gpio", "GPIO H-bridges"},
    ProtocolAlias{"gpio_hbridge", "gpio", "GPIO H-bridges"},
    ProtocolAlias{"adafruit_pca9685", "pca9685", "a PCA9685 PWM board as a differential drive"},
    ProtocolAlias{"pca9685_pwm", "pca9685", "a PCA9685 PWM board as a differential drive"},
    ProtocolAlias{"dynamixel2", "dynamixel", "Dynamixel Protocol 2.0 servos"},
    ProtocolAlias{"dynamixel_protocol2", "dynamixel", "Dynamixel Protocol 2.0 servos"},
    ProtocolAlias{"dynamixel_sdk", "dynamixel", "Dynamixel Protocol 2.0 servos"},
    ProtocolAlias{"feetech_sts", "feetech", "Feetech STS serial bus servos"},
    ProtocolAlias{"mock", "sim_diff_drive", "a simulated differential drive (no hardware)"},
    ProtocolAlias{"sim", "sim_diff_drive", "a simulated differential drive (no hardware)"},
    ProtocolAlias{"simulated", "sim_diff_drive", "a simulated differential drive (no hardware)"},
    ProtocolAlias{"mock_arm", "sim_arm", "a simulated arm (no hardware)"},
};

struct Unserved {
  std::string_view protocol;
  std::string_view advice;
  bool needs_new_plugin = false;  // no plugin of rcand's serves that hardware: say how to get one
};

constexpr std::string_view kBuildOne =
    "a driver plugin that provides it is needed: build one with the SDK (sdk/README.md) and install it into a plugin "
    "path";

// rcand's own protocols (when their package is not installed), then hardware rcand has no plugin for.
constexpr std::array kUnserved{
    Unserved{"sim_diff_drive", "it is rcand's simulated drive, plugin org.rcand.sim_drive in package rcand-plugins-core"},
    Unserved{"sim_arm", "it is rcand's simulated arm, plugin org.rcand.arm in package rcand-plugins-core"},
    Unserved{"pca9685", "plugin org.rcand.pca9685 in package rcand-plugins-hw provides it"},
    Unserved{"pca9685_i2c", "plugin org.rcand.pca9685 in package rcand-plugins-hw provides it"},
    Unserved{"dynamixel", "plugin org.rcand.dynamixel in package rcand-plugins-hw provides it"},
    Unserved{"dynamixel_v2", "plugin org.rcand.dynamixel in package rcand-plugins-hw provides it"},
    Unserved{"gpio", "plugin org.rcand.gpio_motor in package rcand-plugins-hw provides it"},
    Unserved{"feetech", "plugin org.rcand.feetech in package rcand-plugins-hw provides it"},
    Unserved{"pca9685_rc",
             "an Ackermann RC car (steering servo and ESC on a PCA9685): rcand's pca9685 plugin drives a "
             "differential drive only",
             true},
    Unserved{"arduino_serial_json", "plugin org.rcand.arduino in package rcand-plugins-hw provides it"},
    Unserved{"arduino_serial", "motors behind an Arduino's serial firmware: rcand has no plugin for it", true},
    Unserved{"esp32_serial", "motors behind an ESP32's serial firmware: rcand has no plugin for it", true},
    Unserved{"esp32_wifi", "motors behind an ESP32 over Wi-Fi: rcand has no plugin for it", true},
    Unserved{"roboclaw", "a RoboClaw motor controller (packet serial): rcand has no plugin for it", true},
    Unserved{"odrive", "an ODrive motor controller: rcand has no plugin for it", true},
    Unserved{"ev3dev", "LEGO Mindstorms EV3 motors: rcand has no plugin for them", true},
    Unserved{"lego_spike", "LEGO SPIKE Prime hub motors: rcand has no plugin for them", true},
    Unserved{"unitree", "a Unitree quadruped's locomotion controller: rcand has no plugin for it", true},
    Unserved{"ros2", "a ROS 2 bridge: rcand has no plugin for it", true},
    Unserved{"sunfounder_robot_hat",
             "the SunFounder Robot HAT (its microcontroller on I2C drives the motors and servos): rcand has no plugin "
             "for it",
             true},
    Unserved{"oakd", "a Luxonis OAK camera (frames and depth through Luxonis' DepthAI): rcand has no plugin for it", true},
    Unserved{"gpio_hcsr04",
             "an HC-SR04 ultrasonic ranger, a sensor: rcand's obstacle source is the camera's depth "
             "(camera.depth, plugin org.rcand.vision); remove the entry or add a sensor plugin"},
};

}  // namespace

std::optional<ProtocolAlias> protocol_alias(std::string_view written) noexcept {
  for (const auto& alias : kAliases)
    if (same_name(alias.written, written)) return alias;
  return std::nullopt;
}

std::string unserved_protocol_advice(std::string_view protocol) {
  for (const auto& entry : kUnserved) {
    if (!same_name(entry.protocol, protocol)) continue;
    std::string advice(entry.advice);
    if (entry.needs_new_plugin) advice += "; " + std::string(kBuildOne);
    return advice;
  }
  return "";
}

yaml::ConfigDiagnostic with_protocol_advice(yaml::ConfigDiagnostic diagnostic, const std::vector<std::string>& protocols) {
  constexpr std::string_view kUnservedMessage = "no installed plugin provides driver protocol";
  if (!diagnostic.message.starts_with(kUnservedMessage) || !diagnostic.key_path.starts_with("drivers[") ||
      !diagnostic.key_path.ends_with("].protocol"))
    return diagnostic;
  std::size_t index = 0;
  for (const char c : std::string_view(diagnostic.key_path).substr(8)) {
    if (c < '0' || c > '9') break;
    index = index * 10 + static_cast<std::size_t>(c - '0');
    if (index >= protocols.size()) return diagnostic;
  }
  if (index >= protocols.size()) return diagnostic;
  std::string advice = unserved_protocol_advice(protocols[index]);
  // A likely misspelling already names what was meant; anything else gets the way to a plugin.
  if (advice.empty() && diagnostic.message.find("did you mean") == std::string::npos) advice = kBuildOne;
  if (!advice.empty()) diagnostic.message += " (" + advice + ")";
  return diagnostic;
}

}  // namespace rcand::config
