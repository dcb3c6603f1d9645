// rcanctl fleet keygen|enroll|revoke|list (issue 31), run in-process: the private key 0600 and never overwritten, the
// peers file written atomically, a robot enrolled with another key refused unless --replace.
#include <doctest/doctest.h>

#include <nlohmann/json.hpp>

#include <sys/stat.h>

#include <fstream>
#include <sstream>
#include <vector>

#include "fleet_command.hpp"
#include "libs/r2r_wire/message_signature.hpp"
#include "libs/r2r_wire/peers_file.hpp"
#include "temp_dir.hpp"

using nlohmann::json;
using rcand::r2r_wire::Ed25519Key;

namespace {

struct FleetRun {
  int code = -1;
  std::string out, err;
};

FleetRun fleet(std::vector<std::string> args) {
  std::ostringstream out, err;
  FleetRun run;
  run.code = rcand::rcanctl::run_fleet(args, out, err);
  run.out = out.str();
  run.err = err.str();
  return run;
}

unsigned mode_of(const std::filesystem::path& file) {
  struct stat info {};
  REQUIRE(::stat(file.c_str(), &info) == 0);
  return info.st_mode & 0777;
}

std::string text_of(const std::filesystem::path& file) {
  std::ifstream in(file);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

}  // namespace

TEST_CASE("rcanctl fleet keygen: a key pair, the private key mode 600, never overwritten") {
  rcand::test::TempDir dir;
  const std::string out_dir = (dir.path() / "keys").string();
  const auto made = fleet({"keygen", "alpha", "--out", out_dir, "--json"});
  REQUIRE(made.code == 0);
  const json printed = json::parse(made.out);
  const auto private_file = dir.path() / "keys" / "alpha.key";
  const auto public_file = dir.path() / "keys" / "alpha.pub";
  CHECK(printed["private_key_file"] == private_file.string());
  CHECK(mode_of(private_file) == 0600);
  CHECK(mode_of(public_file) == 0644);
  const Ed25519Key key = Ed25519Key::private_from_file(private_file);
  CHECK(key.public_base64() == printed["public_key"]);
  CHECK(Ed25519Key::public_from_file(public_file).verify("m", key.sign("m")));

  const std::string before = text_of(private_file);
  const auto again = fleet({"keygen", "alpha", "--out", out_dir});
  CHECK(again.code == 1);
  CHECK(again.err.find("exists; not overwritten") != std::string::npos);
  CHECK(text_of(private_file) == before);
  CHECK(fleet({"keygen", "../alpha", "--out", out_dir}).code == 2);  // a name is no path
}

TEST_CASE("rcanctl fleet enroll|revoke|list: the peers file, atomic, refusing another key for an enrolled name") {
  rcand::test::TempDir dir;
  const std::string keys = (dir.path() / "keys").string();
  const std::string peers = (dir.path() / "fleet.yaml").string();
  REQUIRE(fleet({"keygen", "alpha", "--out", keys}).code == 0);
  REQUIRE(fleet({"keygen", "bravo", "--out", keys}).code == 0);
  const Ed25519Key alpha = Ed25519Key::private_from_file(keys + "/alpha.key");
  const Ed25519Key bravo = Ed25519Key::private_from_file(keys + "/bravo.key");

  REQUIRE(fleet({"enroll", "--peers-file", peers, "alpha", keys + "/alpha.pub"}).code == 0);
  CHECK(mode_of(peers) == 0644);  // public keys: every robot reads it
  const auto by_base64 = fleet({"enroll", "--peers-file", peers, "bravo", bravo.public_base64(), "--role", "guest", "--json"});
  REQUIRE(by_base64.code == 0);
  CHECK(json::parse(by_base64.out)["action"] == "enrolled");
  auto loaded = rcand::r2r_wire::load_peers_file(peers);  // what every robot reads
  REQUIRE(loaded.peers.size() == 2);
  CHECK(loaded.peers[0].key->verify("m", alpha.sign("m")));
  CHECK(loaded.peers[1].role == rcand::sdk::Role::Guest);

  // The same again: nothing to do. Another key for a name already enrolled: refused, the file untouched.
  CHECK(json::parse(
            fleet({"enroll", "--peers-file", peers, "bravo", keys + "/bravo.pub", "--role", "GUEST", "--json"}).out)["action"] ==
        "already enrolled");
  const std::string before = text_of(peers);
  std::ifstream reader(peers);  // opened before the rewrite: keeps reading the old file whole
  const auto other = fleet({"enroll", "--peers-file", peers, "bravo", keys + "/alpha.pub", "--role", "guest"});
  CHECK(other.code == 1);
  CHECK(other.err.find("'bravo' is enrolled in " + peers + " with another key; --replace to replace it") != std::string::npos);
  CHECK(text_of(peers) == before);
  REQUIRE(fleet({"enroll", "--peers-file", peers, "bravo", keys + "/alpha.pub", "--replace"}).code == 0);
  std::stringstream old_text;
  old_text << reader.rdbuf();
  CHECK(old_text.str() == before);  // replaced by a rename, never rewritten in place
  loaded = rcand::r2r_wire::load_peers_file(peers);
  CHECK(loaded.peers[1].key->verify("m", alpha.sign("m")));
  CHECK(loaded.peers[1].role == rcand::sdk::Role::User);

  const auto listed = json::parse(fleet({"list", "--peers-file", peers, "--json"}).out);
  REQUIRE(listed["peers"].size() == 2);
  CHECK(listed["peers"][0]["public_key"] == alpha.public_base64());
  REQUIRE(fleet({"revoke", "--peers-file", peers, "alpha"}).code == 0);
  CHECK(fleet({"revoke", "--peers-file", peers, "alpha"}).code == 1);
  CHECK(rcand::r2r_wire::load_peers_file(peers).peers.size() == 1);
  std::size_t entries = 0;
  for ([[maybe_unused]] const auto& entry : std::filesystem::directory_iterator(dir.path())) ++entries;
  CHECK(entries == 2);  // keys/ and fleet.yaml: no temporary file left behind

  CHECK(fleet({"enroll", "--peers-file", peers, "charlie", "not-a-key"}).code == 2);
  CHECK(fleet({"enroll", "--peers-file", peers, "charlie", keys + "/alpha.pub", "--role", "boss"}).code == 2);
}
