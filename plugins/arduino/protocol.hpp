// The bridge firmware's protocol (firmware/arduino_l298n_bridge.ino of the reference runtime): one JSON object per
// line, '\n'-terminated, both ways, at 115200 baud.
//   host -> board: {"cmd":"drive","left":L,"right":R} (PWM -255..255), {"cmd":"stop"}, {"cmd":"ping"},
//                  {"cmd":"sensor","id":"hcsr04"}, {"cmd":"servo","pin":3,"angle":90}
//   board -> host: {"ack":true}; {"sensor":"hcsr04","distance_mm":342} (-1: no echo within ~5 m);
//                  {"error":"unknown command"} (also "json parse error", "unknown sensor id")
// Every non-empty line the board reads restarts its 1 s watchdog; when it runs out the board stops the motors.
// Replies carry no request id: they come in the order of the commands.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace rcand::plugins::arduino {

inline constexpr int kMaxPwm = 255;
inline constexpr std::size_t kMaxLineBytes = 256;  // the firmware parses into a 256-byte document

// Each returns one line, '\n' included.
std::string drive_line(int left, int right);  // clamped to -255..255 as the firmware does
std::string stop_line();
std::string ping_line();
std::string sensor_line(std::string_view id);
std::string servo_line(int pin, int angle);  // angle clamped to 0..180

struct Reply {
  enum class Kind { Ack, Sensor, Error, Unknown };
  Kind kind = Kind::Unknown;
  std::string sensor;                       // Sensor: its id
  std::optional<std::int64_t> distance_mm;  // Sensor: the reading (-1: no echo)
  std::string error;                        // Error: the board's words; Unknown: why the line was not understood
};

// One received line (without its '\n'; a trailing '\r' and spaces are ignored). Never throws.
Reply parse_reply(std::string_view line);

// Splits a byte stream into lines. A line longer than kMaxLineBytes is dropped whole (noise on the wire, a board
// printing something else): `overlong()` counts them.
class LineSplitter {
 public:
  void feed(std::string_view bytes);
  // The next complete line, if any (empty lines are skipped).
  std::optional<std::string> next();
  void clear();
  std::uint64_t overlong() const noexcept { return overlong_; }

 private:
  std::string buffer_;
  std::string pending_;
  bool skipping_ = false;
  std::uint64_t overlong_ = 0;
};

}  // namespace rcand::plugins::arduino
