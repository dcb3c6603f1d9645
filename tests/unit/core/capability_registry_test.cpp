#include <doctest/doctest.h>

#include <algorithm>
#include <filesystem>
#include <random>

#include "kernel/registry/capability_registry.hpp"

using namespace rcand;
using namespace rcand::kernel;

namespace {

config::RobotConfig base_config() {
  config::RobotConfig config;
  config.source_file = "robot.rcan.yaml";
  config.robot_name = "rover";
  config.manufacturer = "acme";
  config.model = "r1";
  config.robot_uuid = "1a2b3c4d-0000-0000-0000-000000000000";
  return config;
}

// What the drivers of these manifests (paths in the source tree) imply, read with the kernel's manifest parser.
std::function<std::vector<DriverImplication>(std::string_view)> implications_in(const std::vector<std::string>& files) {
  std::vector<rcand::PluginManifest> manifests;
  for (const auto& file : files) manifests.push_back(rcand::load_manifest(std::filesystem::path(RCAND_SOURCE_DIR) / file));
  return [manifests](std::string_view protocol) {
    for (const auto& manifest : manifests)
      if (const auto* item = rcand::find_provided(manifest, "driver", protocol)) return item->implies;
    return std::vector<DriverImplication>{};
  };
}

// Installed plugins for these tests: every standard capability, one custom one, a drive and a dynamixel (whose
// implications are the shipped manifests').
ProviderLookup installed_everything() {
  ProviderLookup lookup;
  lookup.driver_implies = implications_in({"manifests/dynamixel.json", "manifests/pca9685.json"});
  lookup.driver_interface = [](std::string_view protocol) -> std::optional<std::string> {
    if (protocol == "sim_diff_drive") return std::string("differential_drive");
    if (protocol == "sim_arm") return std::string("joint_arm");
    return std::nullopt;
  };
  lookup.providers = [](std::string_view capability) -> std::vector<std::string> {
    if (capability == "com.acme.unknown") return {};
    return {"org.test." + std::string(capability)};
  };
  return lookup;
}

std::vector<std::string> split(const std::string& text) {
  std::vector<std::string> parts;
  std::size_t start = 0;
  while (start <= text.size()) {
    auto comma = text.find(',', start);
    parts.push_back(text.substr(start, comma == std::string::npos ? std::string::npos : comma - start));
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  return parts;
}

void require_consistent(const Advertisement& ad) {
  const auto config_list = ad.config_view["rcan_protocol"]["capabilities"].get<std::vector<std::string>>();
  const auto discover_list = ad.discover["capabilities"].get<std::vector<std::string>>();
  const auto txt_list = split(ad.txt.at("caps"));
  const auto discover_txt_list = split(ad.discover["txt_record"]["caps"].get<std::string>());
  REQUIRE(config_list == ad.capabilities);
  REQUIRE(discover_list == ad.capabilities);
  REQUIRE(txt_list == ad.capabilities);
  REQUIRE(discover_txt_list == ad.capabilities);
}

}  // namespace

TEST_CASE("standard capabilities carry the §9.2 scopes") {
  CHECK(CapabilityRegistry::minimum_scope("status") == rcand::sdk::Scope::Status);
  CHECK(CapabilityRegistry::minimum_scope("vision") == rcand::sdk::Scope::Status);
  for (auto name : {"nav", "teleop", "chat", "arm"}) CHECK(CapabilityRegistry::minimum_scope(name) == rcand::sdk::Scope::Control);
  CHECK(CapabilityRegistry::minimum_scope("com.acme.gripper") == rcand::sdk::Scope::Control);  // §9.4
  CHECK(standard_capabilities().size() == 6);
}

TEST_CASE("reverse-domain names") {
  CHECK(is_reverse_domain_name("com.acme.gripper"));
  CHECK(is_reverse_domain_name("io.opencastor.lidar"));
  CHECK(is_reverse_domain_name("com.acme.arm_v2"));
  CHECK_FALSE(is_reverse_domain_name("nav"));
  CHECK_FALSE(is_reverse_domain_name("acme.gripper"));
  CHECK_FALSE(is_reverse_domain_name("Com.Acme.Gripper"));
  CHECK_FALSE(is_reverse_domain_name("com..gripper"));
  CHECK_FALSE(is_reverse_domain_name("com.acme."));
  CHECK_FALSE(is_reverse_domain_name("com.acme.1gripper"));
  CHECK_FALSE(is_reverse_domain_name(""));
}

TEST_CASE("auto-detection follows §9.3 only when the list is omitted") {
  auto config = base_config();
  config.drivers.push_back({"d0", "pca9685", {}});
  config.has_camera = true;
  config.has_agent = true;
  SUBCASE("no physics: teleop but not nav") {
    auto plan = plan_capabilities(config, installed_everything());
    CHECK(plan.auto_detected);
    CHECK(plan.names == std::vector<std::string>{"status", "teleop", "vision", "chat"});
  }
  SUBCASE("physics: nav too") {
    config.wheel_circumference_m = 0.2;
    config.turn_time_per_deg_s = 0.01;
    auto plan = plan_capabilities(config, installed_everything());
    CHECK(plan.names == std::vector<std::string>{"status", "nav", "teleop", "vision", "chat"});
  }
  SUBCASE("dynamixel with kinematics: the arm's servos, so arm only (an arm that advertised teleop could not drive)") {
    config.drivers = {{"d0", "dynamixel", {}}};
    config.has_kinematics = true;
    config.has_camera = config.has_agent = false;
    auto plan = plan_capabilities(config, installed_everything());
    CHECK(plan.names == std::vector<std::string>{"status", "arm"});
    CHECK(std::any_of(plan.notes.begin(), plan.notes.end(),
                      [](const std::string& n) { return n.find("read as an arm") != std::string::npos; }));
  }
  SUBCASE("dynamixel without kinematics: a drive (§9.3: teleop, and nav with physics)") {
    config.drivers = {{"d0", "dynamixel", {}}};
    config.has_camera = config.has_agent = false;
    CHECK(plan_capabilities(config, installed_everything()).names == std::vector<std::string>{"status", "teleop"});
  }
  SUBCASE("the names other runtimes write for the same hardware: pca9685_i2c, dynamixel_v2") {
    config.drivers = {{"d0", "pca9685_i2c", {}}, {"d1", "dynamixel_v2", {}}};
    config.has_kinematics = true;
    config.has_camera = config.has_agent = false;
    CHECK(plan_capabilities(config, installed_everything()).names == std::vector<std::string>{"status", "teleop", "arm"});
  }
  SUBCASE("a driver implementing joint_arm implies arm") {
    config.drivers = {{"d0", "sim_arm", {}}};
    config.has_camera = config.has_agent = false;
    CHECK(plan_capabilities(config, installed_everything()).names == std::vector<std::string>{"status", "arm"});
  }
  SUBCASE("a driver implementing differential_drive implies teleop") {
    config.drivers = {{"d0", "sim_diff_drive", {}}};
    config.has_camera = config.has_agent = false;
    auto plan = plan_capabilities(config, installed_everything());
    CHECK(plan.names == std::vector<std::string>{"status", "teleop"});
  }
  SUBCASE("an auto-detected capability without a provider is dropped with a note") {
    ProviderLookup lookup = installed_everything();
    lookup.providers = [](std::string_view capability) -> std::vector<std::string> {
      if (capability == "vision") return {};
      return {"x"};
    };
    auto plan = plan_capabilities(config, lookup);
    CHECK(plan.names == std::vector<std::string>{"status", "teleop", "chat"});
    bool noted = false;
    for (auto& note : plan.notes) noted = noted || note.find("vision") != std::string::npos;
    CHECK(noted);
  }
  SUBCASE("an explicit list disables auto-detection") {
    config.capabilities = std::vector<std::string>{"teleop"};
    auto plan = plan_capabilities(config, installed_everything());
    CHECK_FALSE(plan.auto_detected);
    CHECK(plan.names == std::vector<std::string>{"status", "teleop"});
  }
  SUBCASE("an explicit empty list declares status only") {
    config.capabilities = std::vector<std::string>{};
    CHECK(plan_capabilities(config, installed_everything()).names == std::vector<std::string>{"status"});
  }
}

TEST_CASE("a third-party driver's manifest says what its presence implies: auto-detected with no kernel change") {
  auto config = base_config();
  config.drivers = {{"t0", "acme_tracks", {}}};
  ProviderLookup lookup = installed_everything();
  lookup.driver_implies = implications_in({"tests/unit/core/fixtures/com.acme.tracks.json"});
  SUBCASE("without physics: its custom capability and teleop; nav named in a note") {
    const auto plan = plan_capabilities(config, lookup);
    CHECK(plan.names == std::vector<std::string>{"status", "teleop", "com.acme.tracks"});
    CHECK(std::any_of(plan.notes.begin(), plan.notes.end(),
                      [](const std::string& n) { return n.find("nav not declared") != std::string::npos; }));
  }
  SUBCASE("with §10.2 physics: nav too, standard names in §9's order") {
    config.wheel_circumference_m = 0.2;
    config.turn_time_per_deg_s = 0.01;
    CHECK(plan_capabilities(config, lookup).names == std::vector<std::string>{"status", "nav", "teleop", "com.acme.tracks"});
  }
  SUBCASE("its \"when\" key set: what it reads as instead, the others named in a note") {
    config.doc = {{"acme", {{"crane", {{"boom_m", 2.5}}}}}};
    const auto plan = plan_capabilities(config, lookup);
    CHECK(plan.names == std::vector<std::string>{"status", "com.acme.crane"});
    CHECK(std::find(plan.notes.begin(), plan.notes.end(),
                    "acme_tracks drivers with acme.crane read as a crane: com.acme.crane, not com.acme.tracks or teleop or nav "
                    "(list rcan_protocol.capabilities for a robot that also has those)") != plan.notes.end());
  }
  SUBCASE("the key false or an empty list is unset") {
    for (const auto& crane : {nlohmann::json(false), nlohmann::json::array(), nlohmann::json()}) {
      config.doc = {{"acme", {{"crane", crane}}}};
      CHECK(plan_capabilities(config, lookup).names == std::vector<std::string>{"status", "teleop", "com.acme.tracks"});
    }
  }
  SUBCASE("an implied custom capability no installed plugin provides is dropped with a note") {
    lookup.providers = [](std::string_view capability) -> std::vector<std::string> {
      if (capability == "com.acme.tracks") return {};
      return {"org.test." + std::string(capability)};
    };
    const auto plan = plan_capabilities(config, lookup);
    CHECK(plan.names == std::vector<std::string>{"status", "teleop"});
    CHECK(std::find(plan.notes.begin(), plan.notes.end(),
                    "auto-detected 'com.acme.tracks' dropped: no installed plugin provides it (install the plugin that "
                    "provides it)") != plan.notes.end());
  }
  SUBCASE("without its manifest the driver implies nothing: the kernel knows no protocol") {
    lookup.driver_implies = nullptr;
    CHECK(plan_capabilities(config, lookup).names == std::vector<std::string>{"status"});
  }
}

TEST_CASE("a capability a plugin declares by itself joins the plan when its config key is true") {
  auto config = base_config();
  config.drivers.push_back({"d0", "sim_diff_drive", {}});
  ProviderLookup lookup = installed_everything();
  lookup.declared_when = [] {
    return std::vector<std::pair<std::string, std::string>>{{"org.rcand.fleet", "runtime.r2r.enabled"}};
  };
  SUBCASE("auto-detected list") {
    config.doc = {{"runtime", {{"r2r", {{"enabled", true}}}}}};
    const auto plan = plan_capabilities(config, lookup);
    CHECK(plan.names == std::vector<std::string>{"status", "teleop", "org.rcand.fleet"});
    bool noted = false;
    for (auto& note : plan.notes) noted = noted || note.find("runtime.r2r.enabled is true") != std::string::npos;
    CHECK(noted);
  }
  SUBCASE("explicit list without it: it runs, unadvertised; the three advertisements equal the list (issue 30)") {
    config.doc = {{"runtime", {{"r2r", {{"enabled", true}}}}}};
    config.capabilities = std::vector<std::string>{"teleop"};
    const auto plan = plan_capabilities(config, lookup);
    CHECK(plan.names == std::vector<std::string>{"status", "teleop"});
    CHECK(plan.unadvertised == std::vector<std::string>{"org.rcand.fleet"});
    bool noted = false;
    for (auto& note : plan.notes) noted = noted || note.find("'org.rcand.fleet' runs, not advertised") != std::string::npos;
    CHECK(noted);
    const CapabilityRegistry registry({"rcan://x", "bob", "m"}, plan);
    CHECK(registry.served() == std::vector<std::string>{"status", "teleop", "org.rcand.fleet"});
    CHECK_FALSE(registry.declared("org.rcand.fleet"));
    const auto ad = registry.advertise("ok", 8000);
    CHECK(ad.config_view["rcan_protocol"]["capabilities"] == nlohmann::json{"status", "teleop"});
    CHECK(ad.txt.at("caps") == "status,teleop");
    CHECK(ad.discover["capabilities"] == nlohmann::json{"status", "teleop"});
  }
  SUBCASE("explicit list naming it: advertised, once") {
    config.doc = {{"runtime", {{"r2r", {{"enabled", true}}}}}};
    config.capabilities = std::vector<std::string>{"org.rcand.fleet", "teleop"};
    const auto plan = plan_capabilities(config, lookup);
    CHECK(plan.names == std::vector<std::string>{"status", "org.rcand.fleet", "teleop"});
    CHECK(plan.unadvertised.empty());
  }
  SUBCASE("the key false, absent or not a boolean: not declared") {
    for (const auto& doc : {nlohmann::json{{"runtime", {{"r2r", {{"enabled", false}}}}}}, nlohmann::json::object(),
                            nlohmann::json{{"runtime", {{"r2r", {{"enabled", "yes"}}}}}}, nlohmann::json{{"runtime", 1}}}) {
      config.doc = doc;
      CHECK(plan_capabilities(config, lookup).names == std::vector<std::string>{"status", "teleop"});
    }
  }
}

TEST_CASE("explicit lists are validated with the config position") {
  auto config = base_config();
  config.marks["rcan_protocol.capabilities[1]"] = {"robot.rcan.yaml", 12, 7};
  auto error_of = [&](std::vector<std::string> list) {
    config.capabilities = std::move(list);
    try {
      plan_capabilities(config, installed_everything());
    } catch (const yaml::ConfigError& e) {
      REQUIRE(e.diagnostics().size() == 1);
      return e.diagnostics()[0];
    }
    FAIL("expected a ConfigError");
    return yaml::ConfigDiagnostic{};
  };
  SUBCASE("unknown standard-looking name suggests the closest") {
    auto d = error_of({"status", "navv"});
    CHECK(d.key_path == "rcan_protocol.capabilities[1]");
    CHECK(d.mark.line == 12);
    CHECK(d.mark.column == 7);
    CHECK(d.message.find("did you mean 'nav'") != std::string::npos);
  }
  SUBCASE("a bare name in an RCAN 1.x file is refused; in a file of another RCAN version it is that version's: not served") {
    auto d = error_of({"status", "move"});
    CHECK(d.message.find("'move' is neither a standard capability") != std::string::npos);
    config.rcan_version = "3.0";
    CHECK(error_of({"status", "navv"}).message.find("did you mean 'nav'") != std::string::npos);  // a typo still is one
    config.capabilities = std::vector<std::string>{"status", "move", "teleop"};
    const auto plan = plan_capabilities(config, installed_everything());
    CHECK(plan.names == std::vector<std::string>{"status", "teleop"});
    bool noted = false;
    for (auto& note : plan.notes) noted = noted || note.find("'move' is no RCAN 1.3 capability") != std::string::npos;
    CHECK(noted);
  }
  SUBCASE("nav without §10.2 physics") {
    auto d = error_of({"status", "nav"});
    CHECK(d.message.find("wheel_circumference_m") != std::string::npos);
  }
  SUBCASE("a listed capability nobody provides names the plugin that could") {
    ProviderLookup nobody = installed_everything();
    nobody.providers = [](std::string_view) { return std::vector<std::string>{}; };
    config.capabilities = std::vector<std::string>{"status", "teleop"};
    try {
      plan_capabilities(config, nobody);
      FAIL("expected a ConfigError");
    } catch (const yaml::ConfigError& e) {
      const auto& message = e.diagnostics()[0].message;
      CHECK(message.find("org.rcand.teleop") != std::string::npos);
      CHECK(message.find("rcand-plugins-core") != std::string::npos);
    }
  }
  SUBCASE("a custom name nobody provides") {
    auto d = error_of({"status", "com.acme.unknown"});
    CHECK(d.message.find("no installed plugin") != std::string::npos);
  }
  SUBCASE("a non-reverse-domain custom name") {
    auto d = error_of({"status", "gripper"});
    CHECK(d.message.find("reverse-domain") != std::string::npos);
  }
}

TEST_CASE("config view, mDNS TXT and DISCOVER agree over many configs") {
  std::mt19937 random(20261121);
  const std::vector<std::string> pool{
      "status", "teleop", "nav", "vision", "chat", "arm", "com.acme.gripper", "io.opencastor.lidar"};
  for (int round = 0; round < 500; ++round) {
    auto config = base_config();
    if (random() % 2) {
      config.wheel_circumference_m = 0.21;
      config.turn_time_per_deg_s = 0.008;
    }
    config.has_camera = random() % 2;
    config.has_agent = random() % 2;
    config.has_kinematics = random() % 2;
    for (const char* protocol : {"pca9685", "dynamixel", "sim_diff_drive", "gpio"})
      if (random() % 3 == 0) config.drivers.push_back({std::string("d") + protocol, protocol, {}});
    if (random() % 2) {
      std::vector<std::string> list;
      for (const auto& name : pool)
        if (random() % 2 && (name != "nav" || config.wheel_circumference_m)) list.push_back(name);
      config.capabilities = list;
    }
    const auto plan = plan_capabilities(config, installed_everything());
    CapabilityRegistry registry({"rcan://acme.r1.1a2b3c4d", "rover", "r1"}, plan);
    const auto ad = registry.advertise(round % 2 ? "idle" : "estop", 8000);
    require_consistent(ad);
    REQUIRE(ad.capabilities.front() == "status");
    if (!has_nav_physics(config))
      REQUIRE(std::find(ad.capabilities.begin(), ad.capabilities.end(), "nav") == ad.capabilities.end());
    for (const auto& name : ad.capabilities) REQUIRE(registry.declared(name));
  }
}

TEST_CASE("the DISCOVER document and TXT record carry every docs/protocol.md §5 key") {
  auto config = base_config();
  config.capabilities = std::vector<std::string>{"teleop", "com.acme.gripper"};
  CapabilityRegistry registry({"rcan://acme.r1.1a2b3c4d", "rover", "r1"}, plan_capabilities(config, installed_everything()));
  const auto ad = registry.advertise("estop", 8123);
  for (auto key : {"ruri", "model", "caps", "roles", "role", "version", "name", "status"}) CHECK(ad.txt.count(key) == 1);
  CHECK(ad.txt.size() == 8);
  CHECK(ad.txt.at("caps") == "status,teleop,com.acme.gripper");
  CHECK(ad.txt.at("version") == "1.3.0");
  CHECK(ad.txt.at("status") == "estop");
  CHECK(ad.discover["port"] == 8123);
  CHECK(ad.discover["service_type"] == "_rcan._tcp");
  CHECK(ad.discover["version"] == "1.3.0");
  CHECK(ad.discover["ruri"] == "rcan://acme.r1.1a2b3c4d");
  CHECK(ad.discover["txt_record"]["status"] == "estop");
}
