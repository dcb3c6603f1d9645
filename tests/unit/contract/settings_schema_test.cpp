// The settings schema of rcand/sdk/contract/settings.hpp beyond flat settings: nested objects, lists of objects,
// forms (oneOf), conditions, rules across settings, claims, the manifest check that refuses a malformed schema, and
// the plan rule (plan.hpp). Both hosts call these very functions; contract_test.cpp shows they agree.
#include <doctest/doctest.h>

#include <rcand/sdk/contract/plan.hpp>
#include <rcand/sdk/contract/settings.hpp>

#include <string>
#include <vector>

namespace contract = rcand::sdk::contract;
using nlohmann::json;

namespace {

// A driver with nested settings of every kind the manifests use.
const json kBoardSchema = json::parse(R"({
  "type": "object",
  "required": ["channels"],
  "properties": {
    "bus": {"type": ["integer", "string"], "minimum": 0, "minLength": 1, "default": 1},
    "address": {"type": "integer", "minimum": 3, "maximum": 119, "default": 64,
                "x-claim": {"resource": "i2c-address", "scope": ["/bus"]}},
    "channels": {"type": "object", "required": ["left", "right"],
                 "properties": {"left": {"$ref": "#/$defs/motor"}, "right": {"$ref": "#/$defs/motor"}}},
    "lines": {"type": "array", "items": {"$ref": "#/$defs/line"}},
    "oe_chip": {"type": "string"},
    "oe_line": {"type": "integer"},
    "frequency_hz": {"type": "number", "default": 50},
    "oscillator_hz": {"type": "number", "default": 25000000}
  },
  "dependentRequired": {"oe_chip": ["oe_line"]},
  "x-rules": [{"rule": "oscillator_hz / frequency_hz >= 16384", "at": "frequency_hz", "message": "too fast for the oscillator"}],
  "$defs": {
    "channel": {"type": "integer", "minimum": 0, "maximum": 15, "x-claim": {"resource": "i2c-channel", "scope": ["/bus", "/address"]}},
    "motor": {"type": "object", "oneOf": [
      {"title": "bridge {in1, in2}", "type": "object", "required": ["in1", "in2"],
       "properties": {"in1": {"$ref": "#/$defs/channel"}, "in2": {"$ref": "#/$defs/channel"}}},
      {"title": "esc {esc, min_us?, max_us?}", "type": "object", "required": ["esc"],
       "properties": {"esc": {"$ref": "#/$defs/channel"}, "min_us": {"type": "number", "default": 1000}, "max_us": {"type": "number", "default": 2000}},
       "x-rules": [{"rule": "min_us < max_us", "message": "needs min_us < max_us"}]}]},
    "line": {"type": ["integer", "object"], "minimum": 0, "required": ["line"],
             "properties": {"line": {"type": "integer", "minimum": 0}, "active_low": {"type": "boolean", "default": false}},
             "x-claim": {"resource": "gpio-line", "scope": [{"pointer": "/oe_chip", "default": "/dev/gpiochip0"}], "value": "line"}}
  },
  "examples": [{"id": "board", "channels": {"left": {"in1": 0, "in2": 1}, "right": {"esc": 2}}}]
})");

const contract::SettingsRules kDriver{contract::kDriverEntryKeys, contract::UnknownKeys::Refuse};

std::vector<std::string> problems_of(const json& schema, const json& settings, const contract::SettingsRules& rules = kDriver) {
  std::vector<std::string> out;
  const auto result = contract::validate_settings(schema, settings, rules);
  for (const auto& [key, problem] : result.problems) out.push_back(key + ": " + problem);
  return out;
}

json board(json left, json right, json extra = json::object()) {
  extra["channels"] = {{"left", std::move(left)}, {"right", std::move(right)}};
  return extra;
}

std::string schema_refusal(const json& schema) {
  try {
    contract::check_settings_schema(schema, "config.");
  } catch (const contract::SettingsError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST_CASE("settings schema: nested settings are checked at their own path, with defaults filled in at every level") {
  CHECK(schema_refusal(kBoardSchema) == "");
  const auto result = contract::validate_settings(kBoardSchema, board({{"in1", 0}, {"in2", 1}}, {{"esc", 2}}), kDriver);
  CHECK(result.problems.empty());
  CHECK(result.settings["address"] == 64);
  CHECK(result.settings["channels"]["right"]["min_us"] == 1000);  // the default of the form that matched
  CHECK_FALSE(result.settings["channels"]["left"].contains("min_us"));
  CHECK(problems_of(kBoardSchema, board({{"in1", 16}, {"in2", 1}}, {{"esc", 2}})) ==
        std::vector<std::string>{"channels.left.in1: expected integer in [0, 15], found 16"});
  CHECK(problems_of(kBoardSchema, json::object()) == std::vector<std::string>{"channels: required (object)"});
  CHECK(problems_of(kBoardSchema, {{"channels", {{"left", {{"esc", 1}}}}}}) ==
        std::vector<std::string>{"channels.right: required (object)"});
}

TEST_CASE("settings schema: every problem is named, not only the first") {
  const auto problems =
      problems_of(kBoardSchema, board({{"in1", 0}, {"in2", 99}}, {{"esc", 2}, {"min_us", "low"}}, {{"address", 200}}));
  CHECK(problems == std::vector<std::string>{"address: expected integer in [3, 119], found 200",
                                             "channels.left.in2: expected integer in [0, 15], found 99",
                                             "channels.right.min_us: expected number, found string"});
}

TEST_CASE("settings schema: an unknown key is refused in a driver entry and in any nested object, with a did-you-mean") {
  CHECK(problems_of(kBoardSchema, board({{"in1", 0}, {"in2", 1}}, {{"esc", 2}}, {{"adress", 65}})) ==
        std::vector<std::string>{"adress: unknown key; expected one of: address, bus, channels, frequency_hz, lines, oe_chip, "
                                 "oe_line, oscillator_hz; did you mean 'address'?"});
  // A key of another runtime is no near miss, and a driver entry refuses it all the same.
  CHECK(problems_of(kBoardSchema, board({{"in1", 0}, {"in2", 1}}, {{"esc", 2}}, {{"hardware_id", "x"}})).size() == 1);
  // In a nested object: the form the keys written fit best names what it takes.
  CHECK(problems_of(kBoardSchema, board({{"in1", 0}, {"in2", 1}, {"pwm", 3}}, {{"esc", 2}})) ==
        std::vector<std::string>{"channels.left.pwm: unknown key; expected one of: in1, in2"});
  // The RCAN entry keys: id and protocol are the host's; port, address, ... are settings when the schema is an object
  // schema, kept as written only for the flat map of older manifests.
  CHECK(problems_of(kBoardSchema, board({{"in1", 0}, {"in2", 1}}, {{"esc", 2}}, {{"id", "b"}, {"protocol", "p"}})).empty());
  CHECK(problems_of(kBoardSchema, board({{"in1", 0}, {"in2", 1}}, {{"esc", 2}}, {{"baud_rate", 9600}})).size() == 1);
  CHECK(problems_of(json{{"speed", {{"type", "number"}}}}, {{"baud_rate", 9600}}).empty());
  // A capability's settings keep the lenient rule: a near miss is refused, another key left out for a warning.
  const contract::SettingsRules capability{{}, contract::UnknownKeys::WarnUnlessNearMiss};
  const auto lenient = contract::validate_settings(json{{"speed", {{"type", "number"}}}}, {{"frequency", 5}}, capability);
  CHECK(lenient.problems.empty());
  CHECK(lenient.ignored == std::vector<std::string>{"frequency"});
}

TEST_CASE("settings schema: forms (oneOf) report the form the writer meant, or name the forms") {
  CHECK(problems_of(kBoardSchema, board({{"in1", 0}}, {{"esc", 2}})) ==
        std::vector<std::string>{"channels.left.in2: required (integer in [0, 15])"});
  CHECK(problems_of(kBoardSchema, board({{"esc", 0}, {"in1", 1}}, {{"esc", 2}})) ==
        std::vector<std::string>{"channels.left.in1: unknown key; expected one of: esc, max_us, min_us"});
  CHECK(problems_of(kBoardSchema, board({{"speed", 0}}, {{"esc", 2}})) ==
        std::vector<std::string>{"channels.left: expected one of bridge {in1, in2} | esc {esc, min_us?, max_us?}"});
  CHECK(problems_of(kBoardSchema, board(3, {{"esc", 2}})) ==
        std::vector<std::string>{"channels.left: expected object, found number"});
}

TEST_CASE("settings schema: rules across settings, dependentRequired, and rules that do not apply") {
  CHECK(problems_of(kBoardSchema, board({{"in1", 0}, {"in2", 1}}, {{"esc", 2}, {"min_us", 2100}})) ==
        std::vector<std::string>{"channels.right: needs min_us < max_us (found max_us = 2000, min_us = 2100)"});
  CHECK(problems_of(kBoardSchema, board({{"in1", 0}, {"in2", 1}}, {{"esc", 2}}, {{"frequency_hz", 2000}})) ==
        std::vector<std::string>{
            "frequency_hz: too fast for the oscillator (found frequency_hz = 2000, oscillator_hz = 25000000)"});
  CHECK(problems_of(kBoardSchema, board({{"in1", 0}, {"in2", 1}}, {{"esc", 2}}, {{"oe_chip", "/dev/gpiochip1"}})) ==
        std::vector<std::string>{"oe_line: required with oe_chip"});
  const contract::SettingsRule rule("a == 0 || a * b >= 2000");
  CHECK(rule.holds({{"a", 0}, {"b", 1}}) == true);
  CHECK(rule.holds({{"a", 20}, {"b", 50}}) == false);
  CHECK(rule.holds({{"a", 40}, {"b", 50}}) == true);
  CHECK_FALSE(rule.holds({{"a", 40}}).has_value());  // b not set: the rule does not apply
  CHECK(rule.names() == std::set<std::string>{"a", "b"});
  CHECK_THROWS_AS(contract::SettingsRule("a < < b"), contract::RuleSyntaxError);
  CHECK_THROWS_AS(contract::SettingsRule("(a < b"), contract::RuleSyntaxError);
}

TEST_CASE("settings schema: conditions (if/then, contains, not) and positional items") {
  const json schema = json::parse(R"({"type": "object", "properties": {
    "servos": {"type": "array", "items": {"type": "object", "properties": {"id": {"type": "integer"}, "wheel": {"enum": ["left", "right"]}}},
               "if": {"contains": {"required": ["wheel"]}},
               "then": {"allOf": [{"contains": {"required": ["wheel"], "properties": {"wheel": {"const": "left"}}}},
                                  {"contains": {"required": ["wheel"], "properties": {"wheel": {"const": "right"}}}}],
                        "errorMessage": "a drive needs both a left and a right wheel"}},
    "size": {"type": "array", "prefixItems": [{"type": "integer", "maximum": 100}, {"type": "integer", "maximum": 50}]},
    "keys": {"type": "object", "not": {"required": ["a", "b"]}, "errorMessage": "a or b, not both"}}})");
  CHECK(schema_refusal(schema) == "");
  CHECK(problems_of(schema, {{"servos", {{{"id", 1}, {"wheel", "left"}}, {{"id", 2}, {"wheel", "right"}}}}}).empty());
  CHECK(problems_of(schema, {{"servos", {{{"id", 1}}}}}).empty());
  CHECK(problems_of(schema, {{"servos", {{{"id", 1}, {"wheel", "left"}}}}}) ==
        std::vector<std::string>{"servos: a drive needs both a left and a right wheel"});
  CHECK(problems_of(schema, {{"size", {100, 60}}}) == std::vector<std::string>{"size[1]: expected integer <= 50, found 60"});
  CHECK(problems_of(schema, {{"keys", {{"a", 1}, {"b", 2}}}}) == std::vector<std::string>{"keys: a or b, not both"});
  CHECK(problems_of(schema, {{"keys", {{"a", 1}}}}).empty());
}

TEST_CASE("claims: a pin, channel, address or id named twice is refused, the same thing written two ways included") {
  const auto claims_of = [](const json& settings) {
    const auto result = contract::validate_settings(kBoardSchema, settings, kDriver);
    REQUIRE(result.problems.empty());
    return result.claims;
  };
  // Within one driver: channel 1 is the left bridge's in2 and the right ESC.
  const auto twice =
      contract::claim_conflicts({{"drivers[0]", "driver a", claims_of(board({{"in1", 0}, {"in2", 1}}, {{"esc", 1}}))}});
  REQUIRE(twice.size() == 1);
  CHECK(twice[0].key == "channels.right.esc");
  CHECK(twice[0].problem == "channel 1 of the I2C device 0x40 on /dev/i2c-1 is already claimed by channels.left.in2");
  // Across drivers: bus 1 and /dev/i2c-1 are one bus; 0x40 on it, and the same GPIO line by offset on the default chip.
  const auto a = claims_of(board({{"in1", 0}, {"in2", 1}}, {{"esc", 2}}, {{"lines", {4}}}));
  const auto b =
      claims_of(board({{"in1", 0}, {"in2", 1}}, {{"esc", 2}},
                      {{"bus", "/dev/i2c-1"}, {"lines", {{{"line", 4}}}}, {"oe_chip", "/dev/gpiochip0"}, {"oe_line", 9}}));
  const auto conflicts = contract::claim_conflicts({{"drivers[0]", "driver a", a}, {"drivers[1]", "driver b", b}});
  std::vector<std::string> found;
  for (const auto& c : conflicts) found.push_back(std::to_string(c.instance) + " " + c.key + ": " + c.problem);
  CHECK(found == std::vector<std::string>{
                     "1 address: I2C address 0x40 on /dev/i2c-1 is already claimed by drivers[0].address (driver a)",
                     "1 channels.left.in1: channel 0 of the I2C device 0x40 on /dev/i2c-1 is already claimed by "
                     "drivers[0].channels.left.in1 (driver a)",
                     "1 channels.left.in2: channel 1 of the I2C device 0x40 on /dev/i2c-1 is already claimed by "
                     "drivers[0].channels.left.in2 (driver a)",
                     "1 channels.right.esc: channel 2 of the I2C device 0x40 on /dev/i2c-1 is already claimed by "
                     "drivers[0].channels.right.esc (driver a)",
                     "1 lines[0]: GPIO line 4 on chip gpiochip0 is already claimed by drivers[0].lines[0] (driver a)"});
  // A different address: nothing shared.
  CHECK(contract::claim_conflicts(
            {{"drivers[0]", "a", a},
             {"drivers[1]", "b", claims_of(board({{"in1", 0}, {"in2", 1}}, {{"esc", 2}}, {{"address", 65}}))}})
            .empty());
  // A chip left to be found at start may be any chip: the claim conflicts, and the message says why.
  const contract::Claim unknown_chip{"gpio-line", {nullptr}, 4, "chip_line"};
  const auto maybe = contract::claim_conflicts({{"drivers[0]", "a", a}, {"drivers[1]", "b", {unknown_chip}}});
  REQUIRE(maybe.size() == 1);
  CHECK(maybe[0].problem.find("leaves the chip to be found at start") != std::string::npos);
  // Names are unique within one driver only.
  const contract::Claim joint{"name", {}, "shoulder", "servos[0].joint"};
  CHECK(contract::claim_conflicts({{"drivers[0]", "a", {joint}}, {"drivers[1]", "b", {joint}}}).empty());
  CHECK(contract::claim_conflicts({{"drivers[0]", "a", {joint, joint}}}).size() == 1);
}

TEST_CASE("the manifest check refuses a malformed settings schema, naming the field") {
  const auto with = [](const char* text) { return schema_refusal(json::parse(text)); };
  CHECK(with(R"({"type": "object", "properties": {"a": {"type": "integer", "minumum": 1}}})")
            .starts_with("config.properties.a.minumum: unknown key;"));
  CHECK(with(R"({"type": "object", "properties": {"a": {"$ref": "#/$defs/none"}}})")
            .starts_with("config.properties.a.$ref: expected"));
  CHECK(with(R"({"type": "object", "properties": {"a": {"type": "integer", "default": "x"}}})") ==
        "config.properties.a.default: expected integer, found string");
  CHECK(with(R"({"type": "object", "properties": {"a": {"type": "integer", "maximum": 3, "examples": [1, 5]}}})") ==
        "config.properties.a.examples[1]: expected integer <= 3, found 5");
  CHECK(with(R"({"type": "object", "properties": {"a": {"type": "integer", "x-claim": {"resource": "pin"}}}})")
            .starts_with("config.properties.a.x-claim.resource: expected one of gpio-line, "));
  CHECK(with(R"({"type": "object", "properties": {"a": {"type": "integer", "x-claim": {"resource": "gpio-line"}}}})")
            .starts_with("config.properties.a.x-claim.scope: a gpio-line claim names 1 setting(s)"));
  CHECK(with(R"({"type": "object", "properties": {"a": {"type": "integer"}}, "x-rules": [{"rule": "a < b", "message": "m"}]})") ==
        "config.x-rules[0].rule: 'b' is not a property of this object");
  CHECK(with(R"({"type": "object", "properties": {"a": {"type": "integer"}}, "x-rules": [{"rule": "a <", "message": "m"}]})")
            .starts_with("config.x-rules[0].rule: rule \"a <\": "));
  CHECK(with(R"({"type": "object", "properties": {"a": {"type": "string", "pattern": "(("}}})") ==
        "config.properties.a.pattern: not a valid regular expression");
  CHECK(with(R"({"type": "object", "examples": [{"id": "x", "b": 1}]})") ==
        "config.examples[0]: b: unknown key; this plugin takes no settings");
  CHECK(with(R"({"type": "list"})").starts_with("config.type: a settings schema is an object"));
  // The older flat map is still a schema.
  CHECK(with(R"({"watchdog_ms": {"type": "integer", "minimum": 1, "required": true}})") == "");
}

TEST_CASE("plan: a need whose condition holds and that nothing planned offers is named at the condition's key") {
  const json needs = json::parse(R"({"kind": "capability", "name": "nav", "needs": [{"service": "rcand.obstacle_source/1",
      "what": "the depth zones", "when": ["camera.depth"], "when_any": ["agent.min_obstacle_m", "safety.obstacle_stop_cm"],
      "without": "every move would be refused"}]})");
  const json offers = json::parse(R"({"kind": "capability", "name": "vision", "offers": [{"service": "rcand.obstacle_source/1",
      "what": "the depth zones", "when": ["camera.depth"]}]})");
  CHECK_NOTHROW(contract::check_provided_item(needs, "provides[0]"));
  CHECK_NOTHROW(contract::check_provided_item(offers, "provides[0]"));
  CHECK_THROWS_WITH(contract::check_provided_item(json::parse(R"({"needs": [{"service": "s", "what": "w"}]})"), "provides[0]"),
                    "provides[0].needs[0].when: required: a need holds only under a config condition");
  const contract::PlannedItem nav{"capability", "nav", "org.rcand.nav", needs};
  json teleop_item = needs;
  teleop_item["name"] = "teleop";
  const contract::PlannedItem teleop{"capability", "teleop", "org.rcand.teleop", teleop_item};
  const contract::PlannedItem vision{"capability", "vision", "org.rcand.vision", offers};
  const json robot{{"camera", {{"depth", "synthetic"}}}, {"safety", {{"obstacle_stop_cm", 30}}}};
  const auto unmet = contract::unmet_needs({nav, teleop}, {nav, teleop, vision}, robot);
  REQUIRE(unmet.size() == 1);
  CHECK(unmet[0].key == "camera.depth");
  CHECK(unmet[0].problem ==
        "camera.depth is set, so capability nav and capability teleop need the depth zones (rcand.obstacle_source/1), which "
        "nothing this robot starts offers: add capability vision (plugin org.rcand.vision) to rcan_protocol.capabilities, or "
        "remove camera.depth; as it is, every move would be refused");
  CHECK(contract::unmet_needs({nav, teleop, vision}, {nav, teleop, vision}, robot).empty());
  CHECK(contract::unmet_needs({nav}, {nav, vision}, json{{"camera", {{"depth", false}}}, {"safety", {{"obstacle_stop_cm", 30}}}})
            .empty());
  CHECK(contract::unmet_needs({nav}, {nav, vision}, json{{"camera", {{"depth", "synthetic"}}}}).empty());  // no minimum: no stop
}
