#include <doctest/doctest.h>

#include <string>

#include "libs/rcan/ruri.hpp"

using namespace rcand;

namespace {
Ruri must_parse(std::string_view text, bool wild = false) {
  const RuriParse parsed = parse_ruri(text, wild);
  INFO("RURI: ", std::string(text), " error: ", parsed.error);
  REQUIRE(parsed.ruri);
  CHECK(parsed.error.empty());
  return *parsed.ruri;
}
}  // namespace

TEST_CASE("canonical RURIs parse into their parts") {
  const Ruri r = must_parse("rcan://registry.rcan.dev/acme/rover-2/1a2b3c4d");
  CHECK_FALSE(r.local_form);
  CHECK(r.registry == "registry.rcan.dev");
  CHECK(r.manufacturer == "acme");
  CHECK(r.model == "rover-2");
  CHECK(r.device_id == "1a2b3c4d");
  CHECK_FALSE(r.port);
  CHECK_FALSE(r.capability);

  const Ruri full = must_parse("rcan://rcan.dev/opencastor/rpi_rc_car/550e8400-e29b-41d4-a716-446655440000:8000/nav");
  CHECK(full.device_id == "550e8400-e29b-41d4-a716-446655440000");
  REQUIRE(full.port);
  CHECK(*full.port == 8000);
  REQUIRE(full.capability);
  CHECK(*full.capability == "nav");

  const Ruri custom = must_parse("rcan://rcan.dev/acme/arm/deadbeef/com.acme.gripper");
  CHECK_FALSE(custom.port);
  CHECK(custom.capability == "com.acme.gripper");
  CHECK(must_parse("rcan://rcan.dev/acme/arm/deadbeef:65535").port == 65535);
  CHECK(must_parse("rcan://rcan.dev/acme/arm/deadbeef:1").port == 1);
}

TEST_CASE("local RURIs expand to registry local.rcan") {
  const Ruri r = must_parse("rcan://acme.rover.1a2b3c4d");
  CHECK(r.local_form);
  CHECK(r.registry == "local.rcan");
  CHECK(r.manufacturer == "acme");
  CHECK(r.model == "rover");
  CHECK(r.device_id == "1a2b3c4d");
  CHECK_FALSE(r.capability);

  const Ruri cap = must_parse("rcan://opencastor.rpi_rc_car.kitchen-bot-2/teleop");
  CHECK(cap.device_id == "kitchen-bot-2");  // the local instance is any [a-z0-9-]+
  CHECK(cap.capability == "teleop");
}

TEST_CASE("to_string round-trips both forms") {
  for (const char* text : {"rcan://registry.rcan.dev/acme/rover-2/1a2b3c4d", "rcan://rcan.dev/acme/arm/deadbeef:8000",
                           "rcan://rcan.dev/acme/arm/deadbeef:8000/nav", "rcan://rcan.dev/acme/arm/deadbeef/com.acme.gripper",
                           "rcan://rcan.dev/a/b/550e8400-e29b-41d4-a716-446655440000", "rcan://acme.rover.1a2b3c4d",
                           "rcan://acme.rover.kitchen/teleop"}) {
    CHECK(must_parse(text).to_string() == text);
  }
  for (const char* text : {"rcan://*", "rcan://*/acme/*/*", "rcan://acme.*.*", "rcan://local.rcan/acme/rover/*"})
    CHECK(must_parse(text, true).to_string() == text);
  CHECK(must_parse("*", true).to_string() == "rcan://*");
}

TEST_CASE("bad RURIs are rejected with a message naming the part") {
  struct Bad {
    const char* text;
    const char* names;  // a word the error must contain
  };
  for (const Bad& bad : {
           Bad{"", "rcan://"},
           Bad{"http://rcan.dev/acme/rover/1a2b3c4d", "rcan://"},
           Bad{"rcan:/rcan.dev/acme/rover/1a2b3c4d", "rcan://"},
           Bad{"rcan://", "expected"},
           Bad{"rcan://rcan.dev/acme/rover", "expected"},                     // 3 segments
           Bad{"rcan://rcan.dev/acme/rover/1a2b3c4d/nav/extra", "expected"},  // 6 segments
           Bad{"rcan://rcan.dev/acme/rover/1A2B3C4D", "device-id"},           // uppercase
           Bad{"rcan://rcan.dev/acme/rover/1a2b3c4", "device-id"},            // 7 hex
           Bad{"rcan://rcan.dev/acme/rover/1a2b3c4g", "device-id"},           // not hex
           Bad{"rcan://rcan.dev/acme/rover/550e8400e29b41d4a716446655440000", "device-id"},  // UUID without dashes
           Bad{"rcan://rcan.dev/acme/rover/550e8400-e29b-41d4-a716-44665544000g", "device-id"},
           Bad{"rcan://rcan.dev/acme/rover/1a2b3c4d:0", "port"},
           Bad{"rcan://rcan.dev/acme/rover/1a2b3c4d:65536", "port"},
           Bad{"rcan://rcan.dev/acme/rover/1a2b3c4d:", "port"},
           Bad{"rcan://rcan.dev/acme/rover/1a2b3c4d:80a", "port"},
           Bad{"rcan://rcan.dev/acme/rover/1a2b3c4d:+80", "port"},
           Bad{"rcan://rcan.dev/acme/rover/1a2b3c4d/", "capability"},
           Bad{"rcan://rcan.dev/acme/rover/1a2b3c4d/.nav", "capability"},
           Bad{"rcan://rcan.dev/acme/rover/1a2b3c4d/nav?x=1", "capability"},
           Bad{"rcan://rcan..dev/acme/rover/1a2b3c4d", "registry"},
           Bad{"rcan:///acme/rover/1a2b3c4d", "registry"},
           Bad{"rcan://rcan.dev/Acme/rover/1a2b3c4d", "manufacturer"},
           Bad{"rcan://rcan.dev/acme/ro ver/1a2b3c4d", "model"},
           Bad{"rcan://acme.rover", "expected"},              // local form needs three parts
           Bad{"rcan://acme.rover.one.two", "expected"},
           Bad{"rcan://acme.rover.Kitchen", "instance"},
           Bad{"rcan://acme.rover.kitchen_1", "instance"},
           Bad{"rcan://acme..kitchen", "model"},
           Bad{"rcan://acme.rover.1a2b3c4d:8000", "instance"},  // no port in the local form
           Bad{"rcan://*", "expected"},                          // wildcards only when allowed
           Bad{"*", "rcan://"},
           Bad{"rcan://rcan.dev/acme/*/1a2b3c4d", "model"},
       }) {
    const RuriParse parsed = parse_ruri(bad.text);
    INFO("RURI: ", bad.text);
    CHECK_FALSE(parsed.ruri);
    CHECK(parsed.error.find(bad.names) != std::string::npos);
  }
}

TEST_CASE("wildcards are whole segments only") {
  CHECK_FALSE(parse_ruri("rcan://rcan.dev/acme/rov*/1a2b3c4d", true).ruri);
  CHECK_FALSE(parse_ruri("rcan://*.dev/acme/rover/1a2b3c4d", true).ruri);
  CHECK_FALSE(parse_ruri("rcan://acme.rover.12*", true).ruri);
  CHECK(parse_ruri("rcan://*/*/*/*", true).ruri);
}

TEST_CASE("ruri_matches compares registry, manufacturer, model and device id") {
  const Ruri robot = must_parse("rcan://acme.rover.1a2b3c4d");
  CHECK(ruri_matches(must_parse("rcan://*", true), robot));
  CHECK(ruri_matches(must_parse("*", true), robot));
  CHECK(ruri_matches(must_parse("rcan://acme.rover.1a2b3c4d"), robot));
  CHECK(ruri_matches(must_parse("rcan://acme.rover.1a2b3c4d/nav"), robot));  // capability ignored
  CHECK(ruri_matches(must_parse("rcan://local.rcan/acme/rover/1a2b3c4d:9000"), robot));  // same robot, canonical
  CHECK(ruri_matches(must_parse("rcan://acme.*.*", true), robot));
  CHECK(ruri_matches(must_parse("rcan://*/acme/rover/*", true), robot));
  CHECK_FALSE(ruri_matches(must_parse("rcan://acme.rover.deadbeef"), robot));
  CHECK_FALSE(ruri_matches(must_parse("rcan://acme.arm.*", true), robot));
  CHECK_FALSE(ruri_matches(must_parse("rcan://other.*.*", true), robot));
  CHECK_FALSE(ruri_matches(must_parse("rcan://rcan.dev/acme/rover/1a2b3c4d"), robot));  // another registry
}

TEST_CASE("robot_ruri: metadata.ruri wins, else derived from manufacturer, model and uuid") {
  CHECK(robot_ruri(std::string("rcan://rcan.dev/acme/rover/1a2b3c4d"), "x", "y", "z") ==
        "rcan://rcan.dev/acme/rover/1a2b3c4d");
  CHECK(robot_ruri(std::nullopt, "opencastor", "rpi_rc_car", "550E8400-E29B-41d4-a716-446655440000") ==
        "rcan://opencastor.rpi_rc_car.550e8400");
  CHECK(robot_ruri(std::nullopt, "acme", "rover", "1a2b-3c4d-5e6f") == "rcan://acme.rover.1a2b3c4d");
  CHECK(robot_ruri(std::string(), "acme", "rover", "1a2b3c4d5e6f") == "rcan://acme.rover.1a2b3c4d");
  // Display names are made RURI-safe so the robot's own RURI always parses.
  const std::string derived = robot_ruri(std::nullopt, "Acme Robotics", "Rover.v2", "deadbeef-0000");
  CHECK(derived == "rcan://acme-robotics.rover-v2.deadbeef");
  CHECK(parse_ruri(derived).ruri);
}
