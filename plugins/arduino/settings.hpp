// A `protocol: arduino_serial_json` drivers[] entry, with the reference runtime's field names:
//   port: /dev/ttyACM0    baud: 115200    max_pwm: 255    deadband_pwm: 40    invert_left: false
//   channels: {left_pwm_pin: 5, left_dir_a: 6, left_dir_b: 7, right_pwm_pin: 10, right_dir_a: 8, right_dir_b: 9}
//   ultrasonic: {sensor_type: hcsr04, trigger_pin: 12, echo_pin: 11, poll_hz: 10}
// One entry per board: the board's one serial port is claimed once (the reference runtime's presets list the
// ultrasonic as a second entry on the same port; here it is the `ultrasonic` block of the board's entry).
#pragma once

#include <rcand/sdk/config_view.hpp>

#include <chrono>
#include <map>
#include <optional>
#include <string>

namespace rcand::plugins::arduino {

struct UltrasonicSettings {
  std::string sensor_id = "hcsr04";  // what {"cmd":"sensor","id":...} asks for
  double poll_hz = 10.0;
  std::chrono::milliseconds stale_after{500};  // an older reading is no reading
  bool no_echo_is_clear = false;               // -1 (no echo within range): unavailable unless this is set
  double max_range_cm = 400.0;                 // what a no-echo reading stands for when no_echo_is_clear
};

struct ArduinoSettings {
  std::string port;
  int baud = 115200;
  int max_pwm = 255;
  int deadband_pwm = 40;
  bool invert_left = false, invert_right = false;
  std::map<std::string, int> channels;           // the firmware's wiring, for the record (the sketch fixes the pins)
  std::chrono::milliseconds reply_timeout{200};  // timeout_s
  std::chrono::milliseconds heartbeat{250};      // while moving; the firmware stops the motors after 1 s of silence
  std::chrono::milliseconds halt_deadline{10};
  std::chrono::milliseconds boot_timeout{4000};  // after opening the port (DTR resets the board)
  std::chrono::milliseconds command_timeout{100};
  std::optional<UltrasonicSettings> ultrasonic;

  // Wheel fraction [-1, 1] to the PWM the firmware takes, as the reference driver: 0 stays 0, anything else is at
  // least deadband_pwm and at most max_pwm.
  int pwm_of(double fraction, bool invert) const;

  // Throws sdk::ConfigError naming the key ("ultrasonic.poll_hz: ...").
  static ArduinoSettings from(const sdk::ConfigView& driver);
};

}  // namespace rcand::plugins::arduino
