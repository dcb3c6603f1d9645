// runtime.r2r.peers_file (issue 31): the fleet's peers file parsed and checked with file:line:column, merged with the
// inline peers (a name in both is an error naming both places, also at --check-config), re-read whole on reload, and
// written atomically.
#include <doctest/doctest.h>

#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "libs/config/robot_config.hpp"
#include "libs/r2r_wire/message_signature.hpp"
#include "libs/r2r_wire/peers_file.hpp"
#include "services/r2r/r2r_settings.hpp"
#include "temp_dir.hpp"

using namespace rcand;
using namespace rcand::kernel;
using namespace rcand::services::r2r;
using nlohmann::json;

namespace {

std::string peers_file_error(const std::filesystem::path& file) {
  try {
    r2r_wire::load_peers_file(file);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  FAIL("accepted ", file.string());
  return {};
}

const char* kPeersHeader =
    "rcan_version: \"1.3\"\nmetadata:\n  robot_name: rover-1\n  robot_uuid: \"abcd1234\"\n"
    "  manufacturer: acme\n  model: rover\nruntime:\n  r2r:\n";

}  // namespace

TEST_CASE("peers file: YAML entries shaped as runtime.r2r.peers[], keys inline or in files relative to it") {
  rcand::test::TempDir dir;
  const r2r_wire::Ed25519Key alpha = r2r_wire::Ed25519Key::generate(), bravo = r2r_wire::Ed25519Key::generate();
  dir.write("keys/bravo.pub", bravo.public_pem());
  const auto file = dir.write("fleet.yaml", "# the fleet\npeers:\n  - name: alpha\n    public_key: " + alpha.public_base64() +
                                                "\n  - name: bravo\n    public_key_file: keys/bravo.pub\n    role: owner\n");
  const r2r_wire::LoadedPeers loaded = r2r_wire::load_peers_file(file);
  REQUIRE(loaded.peers.size() == 2);
  CHECK(loaded.peers[0].name == "alpha");
  CHECK(loaded.peers[0].role == sdk::Role::User);  // the default, as for inline peers
  CHECK(loaded.peers[0].key->verify("m", alpha.sign("m")));
  CHECK(loaded.peers[1].role == sdk::Role::Owner);
  CHECK(loaded.peers[1].key->verify("m", bravo.sign("m")));
  CHECK(loaded.where[1] == file.string() + ":5:5");
  // JSON is YAML: a generated file reads as well.
  const auto as_json =
      dir.write("fleet.json", json{{"peers", {{{"name", "alpha"}, {"public_key", alpha.public_base64()}}}}}.dump());
  CHECK(r2r_wire::load_peers_file(as_json).peers.size() == 1);
  CHECK(r2r_wire::load_peers_file(dir.write("empty.yaml", "peers: []\n")).peers.empty());
}

TEST_CASE("peers file: every fault named with file:line:column, never a key's bytes") {
  rcand::test::TempDir dir;
  const std::string key = r2r_wire::Ed25519Key::generate().public_base64();
  auto error_of = [&](const std::string& text) { return peers_file_error(dir.write("p.yaml", text)); };
  const std::string at = (dir.path() / "p.yaml").string();
  CHECK(error_of("peers:\n  - name: a\n    public_key: c2hvcnQ=\n").find(at + ":3:5: error: peers[0].public_key:") == 0);
  CHECK(error_of("peers:\n  - name: a\n    public_key: " + key + "\n  - name: a\n    public_key: " + key + "\n")
            .find(at + ":4:5: error: peers[1].name: 'a' is enrolled twice") == 0);
  CHECK(error_of("peers:\n  - name: a\n    publickey: " + key + "\n").find(at + ":3:5: error: peers[0].publickey: unknown key") ==
        0);
  CHECK(error_of("peers:\n  - public_key: " + key + "\n").find("peers[0]: name is required") != std::string::npos);
  CHECK(error_of("peers:\n  - name: a\n").find("give exactly one of public_key and public_key_file") != std::string::npos);
  CHECK(error_of("peers:\n  - name: a\n    public_key: " + key + "\n    role: boss\n").find(at + ":4:5: error: peers[0].role") ==
        0);
  CHECK(error_of("robots: []\n").find("unknown key 'robots'") != std::string::npos);
  CHECK(error_of("peers: [a\n").find(at + ":") == 0);  // a YAML syntax error, with its position
  CHECK(error_of("peers:\n  - name: a\n    public_key_file: missing.pub\n").find("peers[0].public_key_file") !=
        std::string::npos);
  CHECK(peers_file_error(dir.path() / "absent.yaml").find("cannot read the peers file") != std::string::npos);
  CHECK(error_of("peers:\n  - name: a\n    public_key: " + key.substr(0, 20) + "\n").find(key.substr(0, 20)) ==
        std::string::npos);
}

TEST_CASE("peers file: merged with runtime.r2r.peers; a robot in both is refused naming both places, at load and re-read") {
  rcand::test::TempDir dir;
  const r2r_wire::Ed25519Key alpha = r2r_wire::Ed25519Key::generate(), bravo = r2r_wire::Ed25519Key::generate();
  const auto file = dir.write("fleet.yaml", "peers:\n  - name: alpha\n    public_key: " + alpha.public_base64() + "\n");
  json block{{"peers_file", "fleet.yaml"}, {"peers", {{{"name", "bravo"}, {"public_key", bravo.public_base64()}}}}};
  const R2rSettings settings = load_r2r_settings(block, dir.path());
  REQUIRE(settings.auth.peers.size() == 2);
  CHECK(settings.auth.peers[0].name == "bravo");
  CHECK(settings.auth.peers[1].name == "alpha");

  // Re-read (a SIGHUP reload): the file's new content, all at once; a broken file throws with its line.
  const r2r_wire::Ed25519Key charlie = r2r_wire::Ed25519Key::generate();
  dir.write("fleet.yaml", "peers:\n  - name: charlie\n    public_key: " + charlie.public_base64() + "\n");
  const auto reloaded = reload_peers(settings);
  REQUIRE(reloaded.size() == 2);
  CHECK(reloaded[1].name == "charlie");
  dir.write("fleet.yaml", "peers:\n  - name: charlie\n    public_key: nope\n");
  try {
    reload_peers(settings);
    FAIL("accepted a broken peers file");
  } catch (const std::invalid_argument& e) {
    CHECK(std::string(e.what()).find(file.string() + ":3:5: error: peers[0].public_key") == 0);
  }
  dir.write("fleet.yaml", "peers:\n  - name: bravo\n    public_key: " + bravo.public_base64() + "\n");
  try {
    reload_peers(settings);
    FAIL("accepted a robot both inline and in the file");
  } catch (const std::invalid_argument& e) {
    CHECK(std::string(e.what()) ==
          "peer 'bravo' is both in runtime.r2r.peers[0] and in the peers file at " + file.string() + ":2:5: keep one");
  }
}

TEST_CASE("peers file at load and --check-config: missing, broken, or naming an inline robot: file:line:column") {
  rcand::test::TempDir dir;
  const std::string key = r2r_wire::Ed25519Key::generate().public_base64();
  dir.write("fleet.yaml", "peers:\n  - name: bravo\n    public_key: " + key + "\n");
  auto load_error = [&](const std::string& r2r_lines) {
    try {
      config::parse_robot_config(std::string(kPeersHeader) + r2r_lines, "robot.rcan.yaml", dir.path());
    } catch (const yaml::ConfigError& e) {
      return std::string(e.what());
    }
    FAIL("accepted");
    return std::string();
  };
  const std::string both =
      load_error("    peers_file: fleet.yaml\n    peers:\n      - name: bravo\n        public_key: " + key + "\n");
  CAPTURE(both);
  CHECK(both.find("robot.rcan.yaml:11:9: error: runtime.r2r.peers[0].name: 'bravo' is also in the peers file at " +
                  (dir.path() / "fleet.yaml").string() + ":2:5: keep one") != std::string::npos);
  const std::string missing = load_error("    peers_file: nowhere.yaml\n");
  CHECK(missing.find("robot.rcan.yaml:9:5: error: runtime.r2r.peers_file:") != std::string::npos);
  CHECK(missing.find("cannot read the peers file") != std::string::npos);
  // A public key is no secret: a world-readable peers file passes without a warning.
  const auto loaded =
      config::parse_robot_config(std::string(kPeersHeader) + "    peers_file: fleet.yaml\n", "robot.rcan.yaml", dir.path());
  CHECK(loaded.warnings.empty());
}

TEST_CASE("peers file: written atomically (a new file renamed over the old), mode 0644, read back the same") {
  rcand::test::TempDir dir;
  const auto file = dir.path() / "fleet.yaml";
  const json first{
      {"peers", {{{"name", "alpha"}, {"public_key", r2r_wire::Ed25519Key::generate().public_base64()}, {"role", "USER"}}}}};
  r2r_wire::write_peers_document(file, first);
  CHECK(r2r_wire::read_peers_document(file, false) == first);
  struct stat info {};
  REQUIRE(::stat(file.c_str(), &info) == 0);
  CHECK((info.st_mode & 0777) == 0644);
  // A reader that opened the old file keeps reading it whole while the new one replaces it.
  std::ifstream reader(file);
  json second = first;
  second["peers"].push_back(
      {{"name", "bravo"}, {"public_key", r2r_wire::Ed25519Key::generate().public_base64()}, {"role", "GUEST"}});
  r2r_wire::write_peers_document(file, second);
  std::stringstream old_text;
  old_text << reader.rdbuf();
  CHECK(old_text.str().find("bravo") == std::string::npos);
  CHECK(old_text.str().find("alpha") != std::string::npos);
  CHECK(r2r_wire::read_peers_document(file, false) == second);
  std::size_t entries = 0;
  for ([[maybe_unused]] const auto& entry : std::filesystem::directory_iterator(dir.path())) ++entries;
  CHECK(entries == 1);  // no temporary file left behind
  CHECK(r2r_wire::read_peers_document(dir.path() / "new.yaml", true) == json{{"peers", json::array()}});
}

TEST_CASE("message auth: replace_peers swaps the table in force at once (a SIGHUP reload of the peers file)") {
  AuthSettings open;
  const Authenticator tokens(open);
  const r2r_wire::Ed25519Key alpha = r2r_wire::Ed25519Key::generate();
  MessageAuthenticator auth(tokens, {});
  json m{{"header", {{"version", "1.0"}, {"timestamp", 1'700'000'000.0}, {"source_id", "alpha"}}},
         {"type", "command"},
         {"payload", {{"type", "estop"}}}};
  r2r_wire::sign_message(m, "alpha", alpha);
  auto parsed = r2r_wire::parse_envelope(m.dump());
  REQUIRE(std::holds_alternative<r2r_wire::Envelope>(parsed));
  const r2r_wire::Envelope& e = std::get<r2r_wire::Envelope>(parsed);
  auto verdict = auth.authorize(e, e.received, std::nullopt, sdk::Scope::Status, 1'700'000'000.0);
  REQUIRE(std::holds_alternative<AuthFailure>(verdict));
  CHECK(std::get<AuthFailure>(verdict).message == "unknown signing key 'alpha'");
  auth.replace_peers(
      {{"alpha", sdk::Role::Guest,
        std::make_shared<const r2r_wire::Ed25519Key>(r2r_wire::Ed25519Key::public_from_text(alpha.public_pem()))}});
  CHECK(auth.peer_count() == 1);
  verdict = auth.authorize(e, e.received, std::nullopt, sdk::Scope::Status, 1'700'000'000.0);
  REQUIRE(std::holds_alternative<Principal>(verdict));
  CHECK(std::get<Principal>(verdict).name == "alpha");
}
