#include <doctest/doctest.h>

#include <filesystem>
#include <fstream>

#include "libs/config/robot_config.hpp"
#include "plugins/fleet/fleet_settings.hpp"
#include "services/r2r/r2r_settings.hpp"
#include "temp_dir.hpp"

using namespace rcand;
using namespace rcand::kernel;
using namespace rcand::services::r2r;
using nlohmann::json;
using rcand::plugins::fleet::read_fleet_settings;

namespace {

// The auction's keys as the fleet plugin reads them from the robot config (the R2R table checks them first).
rcand::plugins::fleet::FleetSettings fleet_settings(const json& r2r_block) {
  return read_fleet_settings(rcand::sdk::ConfigView(json{{"runtime", {{"r2r", r2r_block}}}}));
}

std::string invalid_argument(const json& block, const std::filesystem::path& base) {
  try {
    load_r2r_settings(block, base);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  FAIL("accepted ", block.dump());
  return {};
}

const char* kHeader =
    "rcan_version: \"1.3\"\nmetadata:\n  robot_name: rover-1\n  robot_uuid: \"abcd1234\"\n"
    "  manufacturer: acme\n  model: rover\nruntime:\n  r2r:\n";

}  // namespace

TEST_CASE("runtime.r2r: defaults, and every key read with files relative to the config") {
  const R2rSettings defaults = load_r2r_settings(json::object(), "/");
  CHECK(defaults.status_interval == std::chrono::milliseconds(1000));
  CHECK(fleet_settings(json::object()).bid_window_s == 1.0);
  CHECK(fleet_settings(json::object()).cost.seconds_per_task == 30.0);
  CHECK_FALSE(defaults.auth.require_signatures);
  CHECK_FALSE(defaults.private_key);
  CHECK_FALSE(defaults.outbound_token);

  const rcand::test::TempDir dir{"rcand-r2r-settings"};
  const r2r_wire::Ed25519Key own = r2r_wire::Ed25519Key::generate();
  const r2r_wire::Ed25519Key peer = r2r_wire::Ed25519Key::generate();
  dir.write("own.pem", own.private_pem());
  dir.write("peer.pem", peer.public_pem());
  dir.write("r2r.token", "fleet-token\n");
  const json block{{"origin", {{"x", 1.5}, {"y", -2}, {"heading_deg", 90}}},
                   {"status_interval_ms", 250},
                   {"bid_window_ms", 1500},
                   {"cost_per_queued_task_s", 12},
                   {"require_signatures", true},
                   {"replay_window_s", 10},
                   {"private_key_file", "own.pem"},
                   {"token_file", "r2r.token"},
                   {"peers",
                    {{{"name", "bob"}, {"public_key_file", "peer.pem"}, {"role", "owner"}},
                     {{"name", "carol"}, {"public_key", peer.public_base64()}}}},
                   {"udp_port", 9100}};  // a transport's key: not this module's business
  const R2rSettings s = load_r2r_settings(block, dir.path());
  CHECK(s.origin.x_m == 1.5);
  CHECK(s.origin.y_m == -2);
  CHECK(s.origin.heading_deg == 90);
  CHECK(s.status_interval == std::chrono::milliseconds(250));
  const auto fleet = fleet_settings(block);
  CHECK(fleet.bid_window_s == 1.5);
  CHECK(fleet.cost.seconds_per_task == 12);
  CHECK(fleet.origin.x_m == 1.5);
  CHECK(fleet.origin.heading_deg == 90);
  CHECK(s.auth.require_signatures);
  CHECK(s.auth.replay_window_s == 10);
  CHECK(s.outbound_token == "fleet-token");
  REQUIRE(s.private_key);
  CHECK(s.private_key->public_base64() == own.public_base64());
  // Both secrets were written readable by others (mode 644): used, each named in a warning with its chmod.
  std::filesystem::permissions(dir.path() / "own.pem", std::filesystem::perms(0644));
  std::filesystem::permissions(dir.path() / "r2r.token", std::filesystem::perms(0644));
  const auto exposed = load_r2r_settings(block, dir.path()).warnings;
  REQUIRE(exposed.size() == 2);
  CHECK(exposed[0].find("runtime.r2r.token_file: other users may read") == 0);
  CHECK(exposed[1].find("runtime.r2r.private_key_file: other users may read") == 0);
  std::filesystem::permissions(dir.path() / "own.pem", std::filesystem::perms(0600));
  std::filesystem::permissions(dir.path() / "r2r.token", std::filesystem::perms(0600));
  CHECK(load_r2r_settings(block, dir.path()).warnings.empty());
  REQUIRE(s.auth.peers.size() == 2);
  CHECK(s.auth.peers[0].name == "bob");
  CHECK(s.auth.peers[0].role == rcand::sdk::Role::Owner);
  CHECK(s.auth.peers[1].role == rcand::sdk::Role::User);
  CHECK(s.auth.peers[1].key->verify("m", peer.sign("m")));
}

TEST_CASE("runtime.r2r: bad settings name the key and never echo key bytes") {
  const rcand::test::TempDir dir{"rcand-r2r-settings"};
  dir.write("garbage.pem", "-----BEGIN PUBLIC KEY-----\nc2VjcmV0LWJ5dGVz\n-----END PUBLIC KEY-----\n");
  dir.write("empty.token", "\n");
  CHECK(invalid_argument({{"peers", {{{"name", "bob"}, {"public_key_file", "garbage.pem"}}}}}, dir.path())
            .find("runtime.r2r.peers[0].public_key_file") == 0);
  CHECK(invalid_argument({{"peers", {{{"name", "bob"}, {"public_key_file", "garbage.pem"}}}}}, dir.path()).find("c2VjcmV0") ==
        std::string::npos);
  CHECK(invalid_argument({{"peers", {{{"name", "bob"}}}}}, dir.path()).find("exactly one of") != std::string::npos);
  CHECK(invalid_argument({{"peers", {{{"name", "bob"}, {"public_key", "bm9wZQ=="}, {"role", "boss"}}}}}, dir.path())
            .find("runtime.r2r.peers[0].role") == 0);
  CHECK(invalid_argument({{"peers", {{{"public_key", "x"}}}}}, dir.path()).find("runtime.r2r.peers[0].name") == 0);
  CHECK(invalid_argument({{"token_file", "missing.token"}}, dir.path()).find("runtime.r2r.token_file") == 0);
  CHECK(invalid_argument({{"token_file", "empty.token"}}, dir.path()).find("is empty") != std::string::npos);
  CHECK(invalid_argument({{"private_key_file", "missing.pem"}}, dir.path()).find("runtime.r2r.private_key_file") == 0);
  CHECK(invalid_argument({{"require_signatures", true}}, dir.path()).find("private_key_file must be set") != std::string::npos);
  CHECK(invalid_argument({{"status_interval_ms", 0}}, dir.path()).find("runtime.r2r.status_interval_ms") == 0);
  CHECK(invalid_argument({{"origin", {{"x", "north"}}}}, dir.path()).find("runtime.r2r.origin.x") == 0);
}

TEST_CASE("runtime.r2r keys are in the config schema: wrong types stop startup with file:line:column") {
  const std::string yaml = std::string(kHeader) +
                           "    require_signatures: maybe\n"  // line 9
                           "    status_interval_ms: -5\n"     // line 10
                           "    peers:\n"                     // line 11
                           "      - public_key: abc\n"        // line 12
                           "        role: boss\n";            // line 13
  try {
    config::parse_robot_config(yaml, "robot.rcan.yaml", "/srv");
    FAIL("accepted");
  } catch (const yaml::ConfigError& e) {
    const std::string text = e.what();
    CAPTURE(text);
    CHECK(text.find("robot.rcan.yaml:9:5: error: runtime.r2r.require_signatures") != std::string::npos);
    CHECK(text.find("robot.rcan.yaml:10:5: error: runtime.r2r.status_interval_ms") != std::string::npos);
    CHECK(text.find("runtime.r2r.peers[0].name") != std::string::npos);
    CHECK(text.find("robot.rcan.yaml:13:9: error: runtime.r2r.peers[0].role") != std::string::npos);
  }
  const auto loaded = config::parse_robot_config(std::string(kHeader) + "    origin: {x: 1, y: 2}\n    bid_window_ms: 500\n",
                                                 "robot.rcan.yaml", "/srv");
  CHECK(loaded.warnings.empty());
  CHECK(load_r2r_settings(loaded.config.runtime.r2r, "/srv").origin.y_m == 2);
  CHECK(fleet_settings(loaded.config.runtime.r2r).bid_window_s == 0.5);
}

TEST_CASE("runtime.r2r rules across keys are the table's too: refused with file:line:column before R2R starts") {
  const std::string yaml = std::string(kHeader) +
                           "    require_signatures: true\n"                                     // line 9
                           "    peers:\n"                                                       // line 10
                           "      - {name: bob, public_key: abc, public_key_file: bob.pem}\n";  // line 11
  try {
    config::parse_robot_config(yaml, "robot.rcan.yaml", "/srv");
    FAIL("accepted");
  } catch (const yaml::ConfigError& e) {
    const std::string text = e.what();
    CAPTURE(text);
    CHECK(text.find("robot.rcan.yaml:8:3: error: runtime.r2r.private_key_file: required key 'private_key_file' is missing "
                    "(require_signatures is true, so private_key_file must be set)") != std::string::npos);
    CHECK(text.find("robot.rcan.yaml:11:") != std::string::npos);
    CHECK(text.find("error: runtime.r2r.peers[0]: give exactly one of public_key_file and public_key") != std::string::npos);
  }
  // The same rows check a block handed to the reader directly, with the same words.
  CHECK(invalid_argument({{"require_signatures", true}}, "/").find("runtime.r2r.private_key_file: required key") == 0);
  CHECK(invalid_argument({{"max_peers", 0}}, "/") == "runtime.r2r.max_peers: must be between 1 and 1000000, found the integer 0");
}
