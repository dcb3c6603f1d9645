#include "libs/config/plugin_settings.hpp"
#include "libs/config/robot_config.hpp"

#include <doctest/doctest.h>

using nlohmann::json;
using rcand::config::apply_config_schema;
using rcand::config::ConfigSchemaError;

namespace {

const json kSchema = json::parse(R"({
  "watchdog_ms": {"type": "integer", "default": 500, "minimum": 1, "description": "dead-man timeout"},
  "speed": {"type": "number", "minimum": 0, "maximum": 1},
  "driver": {"type": "string", "description": "actuator id"},
  "mode": {"type": "string", "enum": ["fast", "safe"], "default": "safe"},
  "verbose": {"type": "boolean", "default": false},
  "waypoints": {"type": "array"},
  "limits": {"type": "object"},
  "api_key": {"type": "string", "enum": ["sk-allowed"]},
  "port": {"type": "string", "required": true, "description": "serial device"}
})");

std::string schema_error_of(const json& settings, bool allow_unknown = false) {
  try {
    apply_config_schema(kSchema, settings, allow_unknown);
  } catch (const ConfigSchemaError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST_CASE("apply_config_schema fills defaults and keeps given values") {
  const json out = apply_config_schema(kSchema, json{{"port", "/dev/ttyUSB0"}, {"speed", 0.5}}, false);
  CHECK(out["watchdog_ms"] == 500);
  CHECK(out["mode"] == "safe");
  CHECK(out["verbose"] == false);
  CHECK(out["speed"] == 0.5);
  CHECK(out["port"] == "/dev/ttyUSB0");
  CHECK_FALSE(out.contains("driver"));  // no default, not required: stays absent
  const json given = apply_config_schema(kSchema, json{{"port", "p"}, {"watchdog_ms", 20}, {"mode", "fast"}}, false);
  CHECK(given["watchdog_ms"] == 20);
  CHECK(given["mode"] == "fast");
}

TEST_CASE("apply_config_schema: null settings and explicit nulls mean 'not set'") {
  const json schema = json::parse(R"({"watchdog_ms": {"type": "integer", "default": 500}, "name": {"type": "string"}})");
  CHECK(apply_config_schema(schema, json(), false) == json{{"watchdog_ms", 500}});
  CHECK(apply_config_schema(schema, json{{"watchdog_ms", nullptr}, {"name", nullptr}}, false) == json{{"watchdog_ms", 500}});
  CHECK(apply_config_schema(json::object(), json::object(), false) == json::object());
}

TEST_CASE("apply_config_schema checks types") {
  CHECK(schema_error_of({{"port", "p"}, {"watchdog_ms", "500"}}) == "watchdog_ms: expected integer >= 1, found string");
  CHECK(schema_error_of({{"port", "p"}, {"watchdog_ms", 1.5}}) == "watchdog_ms: expected integer >= 1, found number");
  CHECK(schema_error_of({{"port", "p"}, {"speed", true}}) == "speed: expected number in [0, 1], found boolean");
  CHECK(schema_error_of({{"port", 3}}) == "port: expected string, found number");
  CHECK(schema_error_of({{"port", "p"}, {"verbose", "yes"}}) == "verbose: expected boolean, found string");
  CHECK(schema_error_of({{"port", "p"}, {"waypoints", json::object()}}) == "waypoints: expected array, found object");
  CHECK(schema_error_of({{"port", "p"}, {"limits", json::array()}}) == "limits: expected object, found array");
  CHECK(schema_error_of({{"port", "p"}, {"speed", 1}}).empty());  // an integer is a number
  CHECK(schema_error_of(json::array()) == "settings: expected object, found array");
}

TEST_CASE("apply_config_schema checks minimum and maximum") {
  CHECK(schema_error_of({{"port", "p"}, {"watchdog_ms", -3}}) == "watchdog_ms: expected integer >= 1, found -3");
  CHECK(schema_error_of({{"port", "p"}, {"watchdog_ms", 0}}) == "watchdog_ms: expected integer >= 1, found 0");
  CHECK(schema_error_of({{"port", "p"}, {"watchdog_ms", 1}}).empty());
  CHECK(schema_error_of({{"port", "p"}, {"speed", 1.5}}) == "speed: expected number in [0, 1], found 1.5");
  CHECK(schema_error_of({{"port", "p"}, {"speed", -0.1}}) == "speed: expected number in [0, 1], found -0.1");
}

TEST_CASE("apply_config_schema checks enums, without echoing secret-looking values") {
  CHECK(schema_error_of({{"port", "p"}, {"mode", "turbo"}}) == "mode: expected one of \"fast\", \"safe\", found \"turbo\"");
  const std::string secret = schema_error_of({{"port", "p"}, {"api_key", "sk-live-SECRET"}});
  CHECK(secret.find("api_key: expected one of") == 0);
  CHECK(secret.find("SECRET") == std::string::npos);
}

TEST_CASE("apply_config_schema reports missing required settings with their description") {
  CHECK(schema_error_of(json::object()) == "port: required (string: serial device)");
}

TEST_CASE("apply_config_schema rejects unknown keys unless allowed") {
  const std::string message = schema_error_of({{"port", "p"}, {"watchdog", 5}});
  CHECK(message.find("watchdog: unknown key; expected one of: ") == 0);
  CHECK(message.find("watchdog_ms") != std::string::npos);
  CHECK(message.find("did you mean 'watchdog_ms'?") != std::string::npos);

  const json entry = apply_config_schema(kSchema, json{{"id", "left"}, {"protocol", "sim"}, {"port", "p"}}, true);
  CHECK(entry["id"] == "left");
  CHECK(entry["protocol"] == "sim");
  CHECK(entry["watchdog_ms"] == 500);

  CHECK_THROWS_WITH_AS(apply_config_schema(json::object(), json{{"x", 1}}, false),
                       "x: unknown key; this plugin takes no settings", ConfigSchemaError);
}

TEST_CASE("apply_config_schema rejects a malformed schema instead of crashing") {
  CHECK_THROWS_AS(apply_config_schema(json::array(), json::object(), false), ConfigSchemaError);
  CHECK_THROWS_WITH_AS(apply_config_schema(json{{"x", 5}}, json::object(), false), "x: expected object, found number",
                       ConfigSchemaError);
  CHECK_THROWS_AS(apply_config_schema(json{{"x", {{"type", "integer"}, {"minimum", "1"}}}}, json::object(), false),
                  ConfigSchemaError);
}

TEST_CASE("a driver entry keeps its RCAN fields; other keys its plugin does not declare are refused") {
  const json entry = apply_config_schema(
      kSchema,
      json{{"id", "left"}, {"protocol", "sim"}, {"port", "p"}, {"baud_rate", 9600}, {"address", 64}, {"channels", {{"left", 0}}}},
      true);
  CHECK(entry["baud_rate"] == 9600);
  CHECK(entry["channels"]["left"] == 0);
  CHECK(schema_error_of({{"id", "left"}, {"protocol", "sim"}, {"port", "p"}, {"wachdog_ms", 5}}, true)
            .find("wachdog_ms: unknown key; expected one of: ") == 0);
}

TEST_CASE("plugin_settings: a refused setting is a config error at the file:line:column of its key") {
  const auto loaded = rcand::config::parse_robot_config(R"(rcan_version: "1.3"
metadata:
  robot_name: r
  robot_uuid: "abcd1234"
  manufacturer: acme
  model: m
drivers:
  - id: left
    protocol: sim
    port: /dev/ttyS0
    watchdog: 5
  - id: right
    protocol: sim
runtime:
  capabilities:
    teleop: {watchdog_ms: 0}
)",
                                                        "robot.rcan.yaml", "/srv");
  const auto& config = loaded.config;
  const auto error_of = [&](const json& schema, const json& settings, bool driver_entry, const std::string& path) {
    try {
      rcand::config::plugin_settings(config, "org.example.x", schema, settings, driver_entry, path);
    } catch (const rcand::config::ConfigError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  CHECK(error_of(kSchema, config.drivers[0].settings, true, "drivers[0]") ==
        "robot.rcan.yaml:11:5: error: drivers[0].watchdog: unknown key; expected one of: api_key, driver, limits, mode, port, "
        "speed, verbose, watchdog_ms, waypoints; did you mean 'watchdog_ms'? (settings of plugin org.example.x)");
  // A required key that is not written: the position of the entry that should hold it.
  CHECK(error_of(kSchema, config.drivers[1].settings, true, "drivers[1]") ==
        "robot.rcan.yaml:12:5: error: drivers[1].port: required (string: serial device) (settings of plugin org.example.x)");
  const json teleop = json::parse(R"({"watchdog_ms": {"type": "integer", "minimum": 1}})");
  CHECK(error_of(teleop, config.runtime.capabilities["teleop"], false, "runtime.capabilities.teleop") ==
        "robot.rcan.yaml:16:14: error: runtime.capabilities.teleop.watchdog_ms: expected integer >= 1, found 0 (settings of "
        "plugin org.example.x)");
  CHECK(rcand::config::plugin_settings(config, "org.example.x", teleop, json{{"watchdog_ms", 5}}, false, "x") ==
        json{{"watchdog_ms", 5}});
}
