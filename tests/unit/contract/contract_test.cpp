// One contract, two hosts: the same table of requests runs against the SDK's fake host (with the teleop plugin
// compiled in) and against a real rcand on loopback (the same plugin, loaded from the build tree), and both must
// answer each one with the same status, error code and field. A vendor test that passes on the fake host then
// holds on the robot (sdk/include/rcand/sdk/contract/requests.hpp has the rules both hosts call). The same holds for a
// plugin's settings and its manifest's "config" schema (sdk/include/rcand/sdk/contract/settings.hpp).
#include <doctest/doctest.h>

#include <rcand/sdk/testing/fake_host.hpp>
#include <rcand/sdk/testing/recording_drive.hpp>

#include <filesystem>
#include <fstream>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

#include "rcand_process.hpp"

extern "C" const rcand_plugin_descriptor* RCAND_ENTRY_FUNCTION(void);

using nlohmann::json;
using rcand::sdk::Role;

namespace {

struct Case {
  std::string name, method, path;
  json body;
  Role role = Role::Owner;
  bool latched = false;  // the e-stop is latched before the request (and cleared after)
  int status;
  std::string code;   // empty: no error body expected
  std::string field;  // empty: none expected
};

// The robot both hosts serve: teleop over a differential drive, nothing else.
const std::vector<Case>& cases() {
  static const json move{{"type", "move"}, {"linear", 0.1}, {"angular", 0.0}, {"duration_ms", 50}};
  static const std::vector<Case> table{
      {"an action body without a type", "POST", "/api/action", json::object(), Role::Owner, false, 400, "BAD_REQUEST", "type"},
      {"an unknown action type", "POST", "/api/action", {{"type", "fly"}}, Role::Owner, false, 400, "BAD_REQUEST", "type"},
      {"an action of an undeclared standard capability",
       "POST",
       "/api/action",
       {{"type", "grip"}},
       Role::Owner,
       false,
       404,
       "CAPABILITY_NOT_FOUND",
       ""},
      {"an undeclared custom capability", "GET", "/api/cap/com.example.none/state", json(), Role::Owner, false, 404,
       "CAPABILITY_NOT_FOUND", ""},
      {"an undeclared standard capability's endpoint", "POST", "/api/nav/waypoint", json::object(), Role::Owner, false, 404,
       "CAPABILITY_NOT_FOUND", ""},
      {"a move from a guest", "POST", "/api/action", move, Role::Guest, false, 403, "INSUFFICIENT_PRIVILEGES", ""},
      {"a move from a user", "POST", "/api/action", move, Role::User, false, 200, "", ""},
      {"a move while latched", "POST", "/api/action", move, Role::Owner, true, 423, "ESTOP_ACTIVE", ""},
      {"an invalid move",
       "POST",
       "/api/action",
       {{"type", "move"}, {"linear", "fast"}, {"angular", 0}},
       Role::Owner,
       false,
       400,
       "BAD_REQUEST",
       "linear"},
  };
  return table;
}

struct Answer {
  int status;
  json body;
};

void check(const Case& c, const Answer& answer, const char* host) {
  INFO(host << ": " << c.name << " (" << c.method << " " << c.path << ") answered " << answer.body.dump());
  CHECK(answer.status == c.status);
  if (c.status >= 300) {  // the docs/protocol.md §4 error body
    CHECK(answer.body.value("status", 0) == c.status);
    CHECK(answer.body.value("error", "") != "");
    CHECK(answer.body.value("code", "") == c.code);
    if (!c.field.empty()) CHECK(answer.body.value("field", "") == c.field);
  }
}

json teleop_manifest() {
  std::ifstream in(RCAND_SOURCE_DIR "/manifests/teleop.json");
  REQUIRE(in.good());
  return json::parse(in);
}

std::string token_of(Role role) {
  return role == Role::Guest ? "guest-token" : role == Role::User ? "user-token" : "owner-token";
}

}  // namespace

TEST_CASE("contract: the fake host answers the request table as the contract says") {
  rcand::sdk::testing::FakeHost host;
  host.add_driver_instance<rcand::sdk::testing::RecordingDrive>("drive0", host.clock());
  host.load(RCAND_ENTRY_FUNCTION, teleop_manifest());
  host.add_capability("teleop");
  for (const auto& c : cases()) {
    if (c.latched) host.latch_estop("contract test");
    const auto response = host.call(c.method, c.path, c.body, c.role);
    if (c.latched) host.clear_estop();
    check(c, {response.status, response.body}, "fake host");
  }
}

TEST_CASE("contract: a real rcand answers the same request table the same way") {
  json config = rcand::test::sim_config();
  config["drivers"] = json::array({{{"id", "drive0"}, {"protocol", "sim_diff_drive"}}});
  config["rcan_protocol"]["capabilities"] = {"status", "teleop"};
  rcand::test::RcandProcess robot(config);
  for (const auto& c : cases()) {
    if (c.latched) REQUIRE(robot.request("POST", "/api/stop", "owner-token").status == 200);
    int status = 0;
    const json body = robot.json(c.method, c.path, token_of(c.role), c.body.is_null() ? "" : c.body.dump(), &status);
    if (c.latched) REQUIRE(robot.request("POST", "/api/estop/clear", "owner-token").status == 200);
    check(c, {status, body}, "rcand");
  }
}

// ---- every row of the route table (rcand/sdk/contract/door.hpp), generated -----------------------------------------

namespace {

// One request per row of the table the fake host serves (rcand builds the same one from the same rules): the row's
// method ("*": POST, and DELETE), its path (a prefix's '*' made a name), and for a POST /api/action row a body with
// its type, or none at all for the action row itself.
struct Probe {
  std::string method, path;
  json body;
};

std::vector<Probe> probes_of(const std::vector<rcand::sdk::contract::RouteRow>& rows) {
  std::vector<Probe> probes;
  for (const auto& row : rows) {
    std::string path = row.path;
    if (path.ends_with('*')) path = path.substr(0, path.size() - 1) + "probe";
    const json body = row.action_type.empty() ? json::object() : json{{"type", row.action_type}};
    for (const std::string& method : row.method == "*" ? std::vector<std::string>{"POST", "DELETE"} : std::vector{row.method})
      probes.push_back({method, path, body});
  }
  probes.push_back({"POST", "/api/cap/teleop/probe", json::object()});  // a standard capability under /api/cap
  probes.push_back({"POST", "/api/action", json{{"type", "fly"}}});     // a type no row has
  return probes;
}

struct Asked {
  Probe probe;
  Role role;
  bool latched;
};

std::string describe_probe(const Asked& a) {
  return a.probe.method + " " + a.probe.path + " " + a.probe.body.dump() + " as " + std::string(rcand::sdk::role_name(a.role)) +
         (a.latched ? ", latched" : "");
}

}  // namespace

TEST_CASE("contract: every row of the route table gets the same answer from both hosts") {
  rcand::sdk::testing::FakeHost host;
  host.add_driver_instance<rcand::sdk::testing::RecordingDrive>("drive0", host.clock());
  host.load(RCAND_ENTRY_FUNCTION, teleop_manifest());
  host.add_capability("teleop");
  const auto table = host.route_table();
  CHECK(table.refused.empty());
  // teleop's two types, a fallback for every other standard mount and type, /api/cap/* and /api/action itself
  REQUIRE(table.rows.size() >= 10);

  std::vector<Asked> asked;
  for (bool latched : {false, true})
    for (const auto& probe : probes_of(table.rows))
      for (Role role : {Role::Guest, Role::User, Role::Owner}) asked.push_back({probe, role, latched});
  MESSAGE(table.rows.size() << " rows, " << asked.size() << " requests on each host");

  std::vector<Answer> fake;
  for (const auto& a : asked) {
    if (a.latched) host.latch_estop("contract test");
    const auto response = host.call(a.probe.method, a.probe.path, a.probe.body, a.role);
    if (a.latched) host.clear_estop();
    fake.push_back({response.status, response.body});
  }

  json config = rcand::test::sim_config();
  config["drivers"] = json::array({{{"id", "drive0"}, {"protocol", "sim_diff_drive"}}});
  config["rcan_protocol"]["capabilities"] = {"status", "teleop"};
  rcand::test::RcandProcess robot(config);
  bool latched = false;
  for (std::size_t i = 0; i < asked.size(); ++i) {
    const Asked& a = asked[i];
    if (a.latched && !latched) REQUIRE(robot.request("POST", "/api/stop", "owner-token").status == 200);
    latched = a.latched;
    int status = 0;
    const json body = robot.json(a.probe.method, a.probe.path, token_of(a.role), a.probe.body.dump(), &status);
    INFO(describe_probe(a) << ": fake host " << fake[i].body.dump() << ", rcand " << body.dump());
    CHECK(status == fake[i].status);
    if (status >= 300) {
      CHECK(body.value("code", "") == fake[i].body.value("code", ""));
      CHECK(body.value("field", "") == fake[i].body.value("field", ""));
    }
  }
  CHECK(robot.request("POST", "/api/estop/clear", "owner-token").status == 200);
}

// ---- plugin settings and the manifest's "config" schema (rcand/sdk/contract/settings.hpp) ----------------------

namespace {

namespace contract = rcand::sdk::contract;
namespace fs = std::filesystem;

// Teleop's settings as the config gives them (runtime.capabilities.teleop), and the refusal both hosts must give: the
// setting at fault and what is wrong with it, as the contract words it. An empty `key` means the settings are taken.
struct SettingsCase {
  std::string name;
  json settings;
  std::string key, problem;
};

const std::vector<SettingsCase>& settings_cases() {
  static const std::vector<SettingsCase> table{
      {"a wrong type", {{"watchdog_ms", "soon"}}, "watchdog_ms", "expected integer in [1, 60000], found string"},
      {"a value out of range", {{"watchdog_ms", 0}}, "watchdog_ms", "expected integer in [1, 60000], found 0"},
      {"an unknown key, with the allowed ones and a did-you-mean",
       {{"watchdog", 300}},
       "watchdog",
       "unknown key; expected one of: driver, watchdog_ms; did you mean 'watchdog_ms'?"},
      {"good settings", {{"watchdog_ms", 300}, {"driver", "drive0"}}, "", ""},
      {"a key of another runtime (no near miss): taken, the key left out with a warning",
       {{"watchdog_ms", 300}, {"frequency", 50}},
       "",
       ""},
      // Where the capability runs (rcand/sdk/contract/isolation.hpp): keys of the host, beside the plugin's own.
      {"isolation said outright, in process", {{"isolation", "in_process"}, {"watchdog_ms", 300}}, "", ""},
      {"an isolation no host knows",
       {{"isolation", "elsewhere"}},
       "isolation",
       "expected \"process\" or \"in_process\", found \"elsewhere\""},
      {"a memory limit no process runs in",
       {{"isolation_memory_mb", 4}},
       "isolation_memory_mb",
       "expected integer >= 16 (megabytes), found 4"},
  };
  return table;
}

// The refusal as the contract itself gives it: "" when the settings are taken.
std::string contract_refusal(const json& schema, const json& settings) {
  // As both hosts run it by default (rcand without --strict): unknown keys that are no near miss are warnings.
  const auto result = contract::validate_capability_settings(schema, settings, contract::UnknownKeys::WarnUnlessNearMiss);
  return result.problems.empty() ? "" : result.problems.front().key + ": " + result.problems.front().problem;
}

void check_refusal(const SettingsCase& c, const std::string& error, const char* host) {
  INFO(host << ": " << c.name << " (" << c.settings.dump() << ") gave: " << error);
  if (c.key.empty()) {
    CHECK(error.empty());
    return;
  }
  CHECK(error.find(c.key) != std::string::npos);
  CHECK(error.find(c.problem) != std::string::npos);
}

json robot_with_teleop() {
  json config = rcand::test::sim_config();
  config["drivers"] = json::array({{{"id", "drive0"}, {"protocol", "sim_diff_drive"}}});
  config["rcan_protocol"]["capabilities"] = {"status", "teleop"};
  return config;
}

// A plugin folder as a vendor's would be: the sim drive, and teleop with its manifest as `edit` leaves it (the
// libraries are the build tree's, linked in).
void write_plugin_folder(const rcand::test::TempDir& dir, const std::function<void(json&)>& edit) {
  for (const std::string name : {"sim_drive", "teleop"}) {
    std::ifstream in(rcand::test::plugin_dir() / (name + ".json"));
    REQUIRE(in.good());
    json manifest = json::parse(in);
    if (name == "teleop") edit(manifest);
    dir.write(name + ".json", manifest.dump(2));
    const std::string library = manifest["library"].get<std::string>();
    fs::create_symlink(rcand::test::plugin_dir() / library, dir.path() / library);
  }
}

// Teleop's dead-man timeout defaults to 250 ms in this manifest: the move's answer shows it was filled in.
void default_watchdog(json& manifest) { manifest["config"]["properties"]["watchdog_ms"]["default"] = 250; }
// "minumum": a typo in the schema, which the manifest check refuses.
void misspelt_schema(json& manifest) { manifest["config"]["properties"]["watchdog_ms"]["minumum"] = 1; }

const json kMove{{"type", "move"}, {"linear", 0.1}, {"angular", 0.0}};

}  // namespace

TEST_CASE("contract: the settings table is the contract's own answer") {
  for (const auto& c : settings_cases()) {
    INFO(c.name);
    CHECK(contract_refusal(teleop_manifest()["config"], c.settings) == (c.key.empty() ? "" : c.key + ": " + c.problem));
  }
  // A driver entry keeps its RCAN fields (id, protocol, port, ...) beside the plugin's settings; anything else is refused.
  const json schema{{"speed", {{"type", "number"}, {"default", 0.5}}}};
  const json entry =
      contract::apply_settings(schema, {{"id", "d"}, {"protocol", "p"}, {"port", "/dev/ttyS0"}}, contract::kDriverEntryKeys);
  CHECK(entry == json{{"id", "d"}, {"protocol", "p"}, {"port", "/dev/ttyS0"}, {"speed", 0.5}});
  CHECK_THROWS_WITH_AS(contract::apply_settings(schema, {{"id", "d"}, {"sped", 1}}, contract::kDriverEntryKeys),
                       "sped: unknown key; expected one of: speed; did you mean 'speed'?", contract::SettingsError);

  // Unknown keys that are no near miss: left out and named (a warning), or refused when strict (no list given).
  std::vector<std::string> ignored;
  const json lenient = contract::apply_settings(schema, {{"id", "d"}, {"frequency", 50}, {"hardware_id", "x"}},
                                                contract::kDriverEntryKeys, &ignored);
  CHECK(lenient == json{{"id", "d"}, {"speed", 0.5}});
  CHECK(ignored == std::vector<std::string>{"frequency", "hardware_id"});
  CHECK_THROWS_WITH_AS(contract::apply_settings(schema, {{"frequency", 50}}), "frequency: unknown key; expected one of: speed",
                       contract::SettingsError);
  ignored.clear();  // a near miss is refused even when lenient
  CHECK_THROWS_AS(contract::apply_settings(schema, {{"sped", 1}}, {}, &ignored), contract::SettingsError);
}

TEST_CASE("contract: the fake host validates plugin settings as the contract says") {
  for (const auto& c : settings_cases()) {
    rcand::sdk::testing::FakeHost host({{"runtime", {{"capabilities", {{"teleop", c.settings}}}}}});
    host.add_driver_instance<rcand::sdk::testing::RecordingDrive>("drive0", host.clock());
    host.load(RCAND_ENTRY_FUNCTION, teleop_manifest());
    std::string error;
    try {
      host.add_capability("teleop");
    } catch (const rcand::sdk::testing::HostError& e) {
      error = e.what();
    }
    check_refusal(c, error, "fake host");
    CHECK(host.ignored_settings().size() == (c.settings.contains("frequency") ? 1u : 0u));
  }
}

TEST_CASE("contract: a real rcand validates plugin settings the same way") {
  for (const auto& c : settings_cases()) {
    json config = robot_with_teleop();
    config["runtime"]["capabilities"]["teleop"] = c.settings;
    std::string error;
    try {
      rcand::test::RcandProcess robot(config);
    } catch (const std::runtime_error& e) {
      error = e.what();
    }
    check_refusal(c, error, "rcand");
  }
}

TEST_CASE("contract: a default from the manifest is filled in on both hosts") {
  json manifest = teleop_manifest();
  default_watchdog(manifest);
  rcand::sdk::testing::FakeHost host;
  host.add_driver_instance<rcand::sdk::testing::RecordingDrive>("drive0", host.clock());
  host.load(RCAND_ENTRY_FUNCTION, manifest);
  host.add_capability("teleop");
  CHECK(host.call("POST", "/api/action", kMove).body["deadman_ms"] == 250);

  rcand::test::TempDir plugins{"rcand-contract-plugins"};
  write_plugin_folder(plugins, default_watchdog);
  rcand::test::RcandProcess robot(robot_with_teleop(), {plugins.path()});
  CHECK(robot.json("POST", "/api/action", "owner-token", kMove.dump())["deadman_ms"] == 250);
}

TEST_CASE("contract: a malformed config schema is refused at load on both hosts") {
  json manifest = teleop_manifest();
  misspelt_schema(manifest);
  const std::string expected = "config.properties.watchdog_ms.minumum: unknown key";
  CHECK_THROWS_WITH_AS(rcand::sdk::testing::FakeHost().load(RCAND_ENTRY_FUNCTION, manifest),
                       doctest::Contains("invalid-manifest: config.properties.watchdog_ms.minumum: unknown key"),
                       rcand::sdk::testing::LoadError);

  rcand::test::TempDir plugins{"rcand-contract-plugins"};
  write_plugin_folder(plugins, misspelt_schema);
  const auto table =
      rcand::test::run_tool(rcand::test::rcand_binary(), {"--check-plugins", "--plugin-path", plugins.path().string()});
  INFO(table.out);
  CHECK(table.exit_code == 1);
  CHECK(table.out.find("invalid-manifest") != std::string::npos);
  CHECK(table.out.find(expected) != std::string::npos);
}
