#include "libs/manifest/manifest.hpp"

#include <doctest/doctest.h>

#include <unistd.h>
#include <filesystem>
#include <fstream>
#include <string>
#include "temp_dir.hpp"

using nlohmann::json;
using rcand::load_manifest;
using rcand::ManifestError;
using rcand::parse_manifest;
using rcand::ProvidedItem;

namespace {

using rcand::test::TempDir;

json teleop_manifest() {
  return json::parse(R"json({ "id": "org.rcand.teleop", "version": "0.1.0", "library": "rcand_teleop.so",
    "abi": {"major": 1, "minor": 0},
    "description": "Direct real-time motor commands (RCAN §9 teleop)",
    "provides": [ {"kind": "capability", "name": "teleop", "actuates": true},
                  {"kind": "driver", "name": "sim_diff_drive", "actuates": true, "interface": "differential_drive",
                   "fail_safe": "wheels stop"} ],
    "requires": ["differential_drive"],
    "config": { "watchdog_ms": {"type": "integer", "default": 500, "minimum": 1, "description": "dead-man timeout"},
                "driver": {"type": "string", "description": "actuator id (default: the first differential_drive)"} } })json");
}

// The ManifestError message for `doc`, or "" when it parses.
std::string manifest_error_of(const json& doc) {
  try {
    parse_manifest(doc, "/plugins/teleop.json");
  } catch (const ManifestError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST_CASE("parse_manifest reads every field of a valid manifest") {
  const auto m = parse_manifest(teleop_manifest(), "/plugins/teleop/teleop.json");
  CHECK(m.id == "org.rcand.teleop");
  CHECK(m.version == "0.1.0");
  CHECK(m.description == "Direct real-time motor commands (RCAN §9 teleop)");
  CHECK(m.file == std::filesystem::path("/plugins/teleop/teleop.json"));
  CHECK(m.library == std::filesystem::path("/plugins/teleop/rcand_teleop.so"));
  CHECK(m.library.is_absolute());
  CHECK(m.abi_major == 1);
  CHECK(m.abi_minor == 0);
  REQUIRE(m.provides.size() == 2);
  CHECK(m.provides[0] == ProvidedItem{"capability", "teleop", true, "", "", {}, {}});
  CHECK(m.provides[1] == ProvidedItem{"driver", "sim_diff_drive", true, "differential_drive", "", {}, {}});
  CHECK(m.provides[1].fail_safe == "wheels stop");  // the manifest's own: a registration never carries it
  CHECK(m.requires_ == std::vector<std::string>{"differential_drive"});
  CHECK(m.config_schema["watchdog_ms"]["default"] == 500);
}

TEST_CASE("parse_manifest: optional fields default") {
  json doc = teleop_manifest();
  doc.erase("description");
  doc.erase("requires");
  doc.erase("config");
  doc["provides"] = json::parse(R"([{"kind": "capability", "name": "teleop"}])");
  const auto m = parse_manifest(doc, "teleop.json");
  CHECK(m.description.empty());
  CHECK(m.requires_.empty());
  CHECK(m.config_schema == json::object());
  CHECK(m.provides[0].actuates == false);
  CHECK(m.library.is_absolute());  // relative manifest paths resolve against the working directory
}

TEST_CASE("parse_manifest: a capability declared by a config key (\"declared_when\")") {
  json doc = teleop_manifest();
  doc["provides"] = json::parse(R"([{"kind": "capability", "name": "org.rcand.fleet", "declared_when": "runtime.r2r.enabled"}])");
  const auto m = parse_manifest(doc, "fleet.json");
  REQUIRE(m.declared_when.size() == 1);
  CHECK(m.declared_when[0] == rcand::DeclaredWhen{"org.rcand.fleet", "runtime.r2r.enabled"});
  CHECK(m.provides[0] ==
        ProvidedItem{"capability", "org.rcand.fleet", false, "", "", {}, {}});  // registration compares as before
  CHECK(parse_manifest(teleop_manifest(), "teleop.json").declared_when.empty());

  doc["provides"][0]["declared_when"] = "runtime..r2r";
  CHECK(manifest_error_of(doc).find("provides[0].declared_when: expected a dotted config key") != std::string::npos);
  doc["provides"][0]["declared_when"] = true;
  CHECK(manifest_error_of(doc).find("provides[0].declared_when: expected string") != std::string::npos);
  doc["provides"] = json::parse(R"([{"kind": "driver", "name": "d", "declared_when": "runtime.r2r.enabled"}])");
  CHECK(manifest_error_of(doc).find("only a capability is declared by a config key") != std::string::npos);
}

TEST_CASE("parse_manifest: what a driver's presence implies (\"implies\")") {
  json doc = teleop_manifest();
  doc["provides"][1]["implies"] = json::parse(R"([{"capabilities": ["arm"], "when": "physics.kinematics", "reads_as": "an arm"},
                                                  {"capabilities": ["teleop", "nav"], "unless": "physics.kinematics"}])");
  const auto m = parse_manifest(doc, "drive.json");
  CHECK(m.provides[1].implies == std::vector<rcand::DriverImplication>{{{"arm"}, "physics.kinematics", "", "an arm"},
                                                                       {{"teleop", "nav"}, "", "physics.kinematics", ""}});
  CHECK(m.provides[1] == ProvidedItem{"driver", "sim_diff_drive", true, "differential_drive", "", {}, {}});  // not registered
  CHECK(parse_manifest(teleop_manifest(), "teleop.json").provides[1].implies.empty());

  const auto error_with = [&](const char* implies) {
    doc["provides"][1]["implies"] = json::parse(implies);
    return manifest_error_of(doc);
  };
  CHECK(error_with(R"({"capabilities": ["arm"]})").find("provides[1].implies: expected array, found object") !=
        std::string::npos);
  CHECK(error_with(R"([{"when": "physics.kinematics"}])").find("provides[1].implies[0].capabilities: required") !=
        std::string::npos);
  CHECK(error_with(R"([{"capabilities": []}])").find("implies[0].capabilities: expected a non-empty array") != std::string::npos);
  CHECK(error_with(R"([{"capabilities": ["a b"]}])").find("implies[0].capabilities[0]: not a capability name") !=
        std::string::npos);
  CHECK(error_with(R"([{"capabilities": ["arm"], "unless": "physics..kinematics"}])")
            .find("provides[1].implies[0].unless: expected a dotted config key") != std::string::npos);
  CHECK(error_with(R"([{"capabilities": ["arm"], "whne": "physics.kinematics"}])")
            .find("provides[1].implies[0].whne: unknown key") != std::string::npos);
  doc["provides"][1].erase("implies");
  doc["provides"][0]["implies"] = json::parse(R"([{"capabilities": ["arm"]}])");
  CHECK(manifest_error_of(doc).find("provides[0].implies: only a driver's presence implies capabilities") != std::string::npos);
}

TEST_CASE("parse_manifest errors name the file and the field") {
  json doc = teleop_manifest();
  SUBCASE("not an object") {
    CHECK(manifest_error_of(json::array()).find("expected a JSON object, found array") != std::string::npos);
  }
  SUBCASE("missing id") {
    doc.erase("id");
    CHECK(manifest_error_of(doc) == "/plugins/teleop.json: id: required field is missing");
  }
  SUBCASE("bad id") {
    doc["id"] = "has space";
    CHECK(manifest_error_of(doc).find("id: 'has space' is not a reverse-domain id") != std::string::npos);
  }
  SUBCASE("version mistyped") {
    doc["version"] = 1;
    CHECK(manifest_error_of(doc) == "/plugins/teleop.json: version: expected string, found number");
  }
  SUBCASE("library empty") {
    doc["library"] = "";
    CHECK(manifest_error_of(doc) == "/plugins/teleop.json: library: must not be empty");
  }
  SUBCASE("library absolute") {
    doc["library"] = "/usr/lib/x.so";
    CHECK(manifest_error_of(doc).find("library: expected a path relative to the manifest's folder") != std::string::npos);
  }
  SUBCASE("abi missing") {
    doc.erase("abi");
    CHECK(manifest_error_of(doc) == "/plugins/teleop.json: abi: required field is missing");
  }
  SUBCASE("abi.major mistyped") {
    doc["abi"]["major"] = "1";
    CHECK(manifest_error_of(doc) == "/plugins/teleop.json: abi.major: expected integer, found string");
  }
  SUBCASE("abi.minor missing") {
    doc["abi"].erase("minor");
    CHECK(manifest_error_of(doc) == "/plugins/teleop.json: abi.minor: required field is missing");
  }
  SUBCASE("abi.minor negative") {
    doc["abi"]["minor"] = -1;
    CHECK(manifest_error_of(doc).find("abi.minor: expected an integer in [0, 65535], found -1") != std::string::npos);
  }
  SUBCASE("isolation of a driver: drivers run in rcand, where a halt always reaches them") {
    doc["provides"][1]["isolation"] = "process";
    CHECK(manifest_error_of(doc) ==
          "/plugins/teleop.json: provides[1].isolation: only a capability runs in a process of its own");
  }
  SUBCASE("isolation unknown") {
    doc["provides"][0]["isolation"] = "sandbox";
    CHECK(manifest_error_of(doc) ==
          "/plugins/teleop.json: provides[0].isolation: expected \"process\" or \"in_process\", found \"sandbox\"");
  }
  SUBCASE("isolation_needs names something no sandbox grants") {
    doc["provides"][0]["isolation_needs"] = {"network", "gpio"};
    CHECK(manifest_error_of(doc) ==
          "/plugins/teleop.json: provides[0].isolation_needs: expected \"network\", \"video\" or "
          "\"serial\" (what its process may use beyond the sandbox), found \"gpio\"");
  }
  SUBCASE("isolation_needs of a driver") {
    doc["provides"][1]["isolation_needs"] = {"serial"};
    CHECK(manifest_error_of(doc) ==
          "/plugins/teleop.json: provides[1].isolation_needs: only a capability runs in a process of its own");
  }
  SUBCASE("provides not an array") {
    doc["provides"] = "teleop";
    CHECK(manifest_error_of(doc) == "/plugins/teleop.json: provides: expected array, found string");
  }
  SUBCASE("provides empty") {
    doc["provides"] = json::array();
    CHECK(manifest_error_of(doc).find("provides: must list at least one") != std::string::npos);
  }
  SUBCASE("provides kind unknown") {
    doc["provides"][1]["kind"] = "sensor";
    CHECK(manifest_error_of(doc) ==
          "/plugins/teleop.json: provides[1].kind: expected \"capability\" or \"driver\", found \"sensor\"");
  }
  SUBCASE("provides name missing") {
    doc["provides"][0].erase("name");
    CHECK(manifest_error_of(doc) == "/plugins/teleop.json: provides[0].name: required field is missing");
  }
  SUBCASE("actuates mistyped") {
    doc["provides"][0]["actuates"] = "yes";
    CHECK(manifest_error_of(doc) == "/plugins/teleop.json: provides[0].actuates: expected boolean, found string");
  }
  SUBCASE("actuating driver without interface") {
    doc["provides"][1].erase("interface");
    CHECK(manifest_error_of(doc).find("provides[1].interface: required for an actuating driver") != std::string::npos);
  }
  SUBCASE("interface on a capability") {
    doc["provides"][0]["interface"] = "differential_drive";
    CHECK(manifest_error_of(doc).find("provides[0].interface: only drivers") != std::string::npos);
  }
  SUBCASE("listed twice") {
    doc["provides"].push_back(doc["provides"][0]);
    CHECK(manifest_error_of(doc).find("provides[2].name: capability 'teleop' is listed twice") != std::string::npos);
  }
  SUBCASE("requires mistyped") {
    doc["requires"] = json::array({"differential_drive", 3});
    CHECK(manifest_error_of(doc) == "/plugins/teleop.json: requires[1]: expected string, found number");
  }
  SUBCASE("config entry without type") {
    doc["config"]["watchdog_ms"].erase("type");
    CHECK(manifest_error_of(doc).find("/plugins/teleop.json: config.watchdog_ms.type: required") == 0);
  }
  SUBCASE("config type unknown") {
    doc["config"]["watchdog_ms"]["type"] = "int";
    CHECK(manifest_error_of(doc).find("config.watchdog_ms.type: expected one of string, number, integer") != std::string::npos);
  }
  SUBCASE("config default violates its own minimum") {
    doc["config"]["watchdog_ms"]["default"] = 0;
    CHECK(manifest_error_of(doc) == "/plugins/teleop.json: config.watchdog_ms.default: expected integer >= 1, found 0");
  }
  SUBCASE("config attribute misspelt") {
    doc["config"]["watchdog_ms"]["minumum"] = 1;
    const std::string message = manifest_error_of(doc);
    CHECK(message.find("config.watchdog_ms.minumum: unknown key") != std::string::npos);
    CHECK(message.find("did you mean 'minimum'?") != std::string::npos);
  }
  SUBCASE("config minimum on a string") {
    doc["config"]["driver"]["minimum"] = 1;
    CHECK(manifest_error_of(doc).find("config.driver.minimum: only allowed for number and integer") != std::string::npos);
  }
  SUBCASE("config enum of the wrong type") {
    doc["config"]["driver"]["enum"] = json::array({"left", 2});
    CHECK(manifest_error_of(doc).find("config.driver.enum: 2 is not a string") != std::string::npos);
  }
  SUBCASE("config not an object") {
    doc["config"] = json::array();
    CHECK(manifest_error_of(doc) == "/plugins/teleop.json: config: expected object, found array");
  }
  SUBCASE("unknown top-level keys are allowed (newer manifests may add fields)") {
    doc["license"] = "Apache-2.0";
    CHECK(manifest_error_of(doc).empty());
  }
}

TEST_CASE("load_manifest reads a file and reports bad JSON and missing files with the file name") {
  TempDir dir{"rcand-manifest"};
  const auto good = dir.path() / "teleop.json";
  std::ofstream(good) << teleop_manifest().dump(2);
  const auto m = load_manifest(good);
  CHECK(m.id == "org.rcand.teleop");
  CHECK(m.library == dir.path() / "rcand_teleop.so");

  const auto bad = dir.path() / "bad.json";
  std::ofstream(bad) << R"({ "id": "x" "version": "1" })";
  try {
    load_manifest(bad);
    FAIL("bad JSON was accepted");
  } catch (const ManifestError& e) {
    const std::string message = e.what();
    CHECK(message.find(bad.string() + ": (document): invalid JSON") == 0);
    CHECK(message.find("[json.exception") == std::string::npos);
  }

  CHECK_THROWS_WITH_AS(load_manifest(dir.path() / "absent.json"), doctest::Contains("absent.json: (file): cannot be read"),
                       ManifestError);
}
