// swarm.yaml (seed §15.2): MUST fields with line-numbered errors, defaults, tags, and tokens kept out of messages.
#include <doctest/doctest.h>

#include <filesystem>
#include <fstream>

#include "libs/swarm/swarm_registry.hpp"

using namespace rcand::swarm;

namespace {

std::string errors_of(const std::string& yaml) {
  try {
    parse_swarm(yaml, "swarm.yaml");
  } catch (const SwarmError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST_CASE("the seed's example parses with every field; port defaults to 8000") {
  const auto registry = parse_swarm(R"(# config/swarm.yaml — RCAN Swarm Node Registry
nodes:
  - name: "alex"
    host: "alex.local"
    ip: "192.168.68.91" # static IP fallback
    port: 8001
    token: "secret-alex"
    rcan: "~/OpenCastor/alex.rcan.yaml"
    tags: [rpi5, camera, i2c, rover]
    added: "2026-02-21"
  - name: bob
    host: 10.0.0.2
    token: secret-bob
)",
                                    "swarm.yaml");
  REQUIRE(registry.nodes.size() == 2);
  const auto& alex = registry.nodes[0];
  CHECK(alex.name == "alex");
  CHECK(alex.host == "alex.local");
  CHECK(alex.ip == "192.168.68.91");
  CHECK(alex.port == 8001);
  CHECK(alex.token == "secret-alex");
  CHECK(alex.rcan == "~/OpenCastor/alex.rcan.yaml");
  CHECK(alex.tags == std::vector<std::string>{"rpi5", "camera", "i2c", "rover"});
  CHECK(alex.added == "2026-02-21");
  CHECK(alex.line == 3);
  CHECK(alex.has_tag("camera"));
  CHECK_FALSE(alex.has_tag("arm"));
  const auto& bob = registry.nodes[1];
  CHECK(bob.port == 8000);
  CHECK_FALSE(bob.ip.has_value());
  CHECK(bob.tags.empty());
  CHECK(bob.address() == "10.0.0.2:8000");
  CHECK(registry.find("bob") == &registry.nodes[1]);
  CHECK(registry.find("carol") == nullptr);
  CHECK(registry.warnings.empty());
}

TEST_CASE("missing MUST fields are errors naming the entry, the field and the line") {
  const auto text = errors_of(R"(nodes:
  - name: alex
    host: alex.local
    token: t1
  - name: bob
    token: t2
  - host: carol.local
    token: t3
  - name: dave
    host: dave.local
)");
  CHECK(text.find("swarm.yaml:5:5: error: nodes[1].host: missing") != std::string::npos);
  CHECK(text.find("swarm.yaml:7:5: error: nodes[2].name: missing") != std::string::npos);
  CHECK(text.find("swarm.yaml:9:5: error: nodes[3].token: missing") != std::string::npos);
  CHECK(text.find("nodes[0]") == std::string::npos);
}

TEST_CASE("wrong types and values are errors; the token value never appears in any message") {
  const auto text = errors_of(R"(nodes:
  - name: alex
    host: alex.local
    token: [not, a, string, super-secret-token]
    port: 99999
    ip: not-an-ip
    tags: rover
  - name: alex
    host: x
    token: another-secret
)");
  CHECK(text.find("swarm.yaml:4:12: error: nodes[0].token: must be a string") != std::string::npos);
  CHECK(text.find("nodes[0].port: must be an integer from 1 to 65535") != std::string::npos);
  CHECK(text.find("nodes[0].ip: 'not-an-ip' is not an IP address") != std::string::npos);
  CHECK(text.find("nodes[0].tags: must be a list of strings") != std::string::npos);
  CHECK(text.find("super-secret-token") == std::string::npos);
  CHECK(text.find("another-secret") == std::string::npos);

  const auto dup = errors_of("nodes:\n  - {name: a, host: h, token: s1}\n  - {name: a, host: h2, token: s2}\n");
  CHECK(dup.find("swarm.yaml:3:") != std::string::npos);
  CHECK(dup.find("nodes[1].name: duplicate node name 'a'") != std::string::npos);
  CHECK(dup.find("s2") == std::string::npos);
}

TEST_CASE("the document's shape: nodes list required, invalid YAML located, unknown keys warned") {
  CHECK(errors_of("").find("needs a top-level 'nodes:' list") != std::string::npos);
  CHECK(errors_of("peers: []\n").find("swarm.yaml:1:1: error: nodes: missing") != std::string::npos);
  CHECK(errors_of("nodes: {a: 1}\n").find("nodes: must be a list") != std::string::npos);
  CHECK(errors_of("nodes:\n  - name: [unclosed\n").find("swarm.yaml:") != std::string::npos);
  CHECK(errors_of("nodes:\n  - just-a-string\n").find("swarm.yaml:2:5: error: nodes[0]: must be a mapping") != std::string::npos);
  CHECK(parse_swarm("nodes:\n", "s").nodes.empty());
  CHECK(parse_swarm("nodes: []\n", "s").nodes.empty());

  const auto registry = parse_swarm("nodes:\n  - {name: a, host: h, token: s, tag: [x]}\n", "swarm.yaml");
  REQUIRE(registry.warnings.size() == 1);
  CHECK(registry.warnings[0].find("swarm.yaml:2:") == 0);
  CHECK(registry.warnings[0].find("unknown key 'tag' (did you mean 'tags'?)") != std::string::npos);

  // A mistyped line that puts the token into a key (found by fuzz_swarm_yaml): the key is not quoted back.
  const auto typo = parse_swarm("nodes:\n  - name: a\n    host: h\n    token: \"secret-token-a\"\n"
                                "    token0 \"secret-token-an: x\n", "swarm.yaml");
  REQUIRE(typo.warnings.size() == 1);
  CHECK(typo.warnings[0].find("secret-token-a") == std::string::npos);
  CHECK(typo.warnings[0].find("swarm.yaml:5:5: warning: nodes[0]: unknown key (not quoted: it contains a token)") == 0);
}

TEST_CASE("load_swarm_file: a missing file is one clear error") {
  try {
    load_swarm_file("/nonexistent/dir/swarm.yaml");
    FAIL("expected SwarmError");
  } catch (const SwarmError& e) {
    CHECK(std::string(e.what()) == "/nonexistent/dir/swarm.yaml: error: cannot read the swarm file: No such file or directory");
  }
  const auto file = std::filesystem::temp_directory_path() / "rcand-swarm-registry-test.yaml";
  std::ofstream(file) << "nodes:\n  - {name: a, host: 127.0.0.1, port: 9, token: t}\n";
  const auto registry = load_swarm_file(file);
  CHECK(registry.source == file);
  CHECK(registry.nodes.at(0).port == 9);
  std::filesystem::remove(file);
}
