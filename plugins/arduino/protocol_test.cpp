// The bridge firmware's JSON-lines protocol as the driver writes and reads it (firmware/arduino_l298n_bridge.ino).
#include <doctest/doctest.h>

#include <nlohmann/json.hpp>

#include "protocol.hpp"
#include "settings.hpp"

using namespace rcand::plugins::arduino;
using nlohmann::json;

TEST_CASE("arduino protocol: each command is one JSON object on one line, as the firmware parses it") {
  CHECK(json::parse(drive_line(150, -100)) == json{{"cmd", "drive"}, {"left", 150}, {"right", -100}});
  CHECK(json::parse(drive_line(900, -900)) == json{{"cmd", "drive"}, {"left", 255}, {"right", -255}});  // clamped
  CHECK(stop_line() == "{\"cmd\":\"stop\"}\n");
  CHECK(ping_line() == "{\"cmd\":\"ping\"}\n");
  CHECK(json::parse(sensor_line("hcsr04")) == json{{"cmd", "sensor"}, {"id", "hcsr04"}});
  CHECK(json::parse(servo_line(3, 200)) == json{{"cmd", "servo"}, {"pin", 3}, {"angle", 180}});
  for (const auto& line : {drive_line(1, 2), stop_line(), ping_line(), sensor_line("hcsr04"), servo_line(3, 90)}) {
    CHECK(line.back() == '\n');
    CHECK(line.find('\n') == line.size() - 1);
    CHECK(line.size() < kMaxLineBytes);
  }
}

TEST_CASE("arduino protocol: the firmware's replies, with println's \\r, and what is not one") {
  CHECK(parse_reply("{\"ack\":true}\r").kind == Reply::Kind::Ack);
  const auto sensor = parse_reply(R"({"sensor":"hcsr04","distance_mm":342})");
  CHECK(sensor.kind == Reply::Kind::Sensor);
  CHECK(sensor.sensor == "hcsr04");
  CHECK(sensor.distance_mm == 342);
  CHECK(parse_reply(R"({"sensor":"hcsr04","distance_mm":-1})").distance_mm == -1);  // no echo
  const auto error = parse_reply(R"({"error":"unknown command"})");
  CHECK(error.kind == Reply::Kind::Error);
  CHECK(error.error == "unknown command");
  for (const char* junk : {"", "garbage", "{\"ack\":false}", "[1,2]", "{\"other\":1}", "{\"ack\":tr"})
    CHECK(parse_reply(junk).kind == Reply::Kind::Unknown);
}

TEST_CASE("arduino protocol: lines split across reads, empty lines skipped, an overlong line dropped whole") {
  LineSplitter splitter;
  splitter.feed("{\"ack\":");
  CHECK_FALSE(splitter.next());
  splitter.feed("true}\r\n\n  \r\n{\"error\":\"x\"}\n");
  CHECK(splitter.next() == std::string("{\"ack\":true}"));
  CHECK(splitter.next() == std::string("{\"error\":\"x\"}"));
  CHECK_FALSE(splitter.next());
  splitter.feed(std::string(kMaxLineBytes + 10, 'x'));
  splitter.feed("tail\n{\"ack\":true}\n");
  CHECK(splitter.next() == std::string("{\"ack\":true}"));
  CHECK(splitter.overlong() == 1);
}

TEST_CASE("arduino settings: wheel fractions to PWM as the reference driver (deadband, max, invert)") {
  ArduinoSettings s;
  s.max_pwm = 200;
  s.deadband_pwm = 40;
  CHECK(s.pwm_of(0.0, false) == 0);
  CHECK(s.pwm_of(1.0, false) == 200);
  CHECK(s.pwm_of(-1.0, false) == -200);
  CHECK(s.pwm_of(0.5, false) == 100);
  CHECK(s.pwm_of(0.05, false) == 40);  // below the deadband: raised to it
  CHECK(s.pwm_of(-0.05, false) == -40);
  CHECK(s.pwm_of(0.5, true) == -100);
  CHECK(s.pwm_of(7.0, false) == 200);
  CHECK(s.pwm_of(std::nan(""), false) == 0);
}
