// libFuzzer target: a swarm.yaml node registry from bytes (parse_swarm, what load_swarm_file runs on the file).
// Only SwarmError may escape, with at least one error naming the file; an accepted registry has unique, non-empty
// names, hosts and tokens, and no message (error or warning) quotes a token.
#include <cstddef>
#include <cstdint>
#include <set>
#include <string>
#include <string_view>

#include "fuzz_check.hpp"
#include "libs/swarm/swarm_registry.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view yaml(reinterpret_cast<const char*>(data), size);
  try {
    const auto registry = rcand::swarm::parse_swarm(yaml, "fuzz-swarm.yaml");
    std::set<std::string> names;
    for (const auto& node : registry.nodes) {
      RCAND_FUZZ_CHECK(!node.name.empty() && !node.host.empty() && !node.token.empty(), "a node has name, host, token");
      RCAND_FUZZ_CHECK(names.insert(node.name).second, "node names are unique");
      RCAND_FUZZ_CHECK(node.port != 0, "a node's port is not 0");
      for (const auto& warning : registry.warnings)
        if (node.token.size() >= 8)
          RCAND_FUZZ_CHECK(warning.find(node.token) == std::string::npos, "a warning quotes a token");
    }
  } catch (const rcand::swarm::SwarmError& error) {
    RCAND_FUZZ_CHECK(!error.errors().empty(), "a SwarmError carries an error");
    for (const auto& message : error.errors())
      RCAND_FUZZ_CHECK(message.rfind("fuzz-swarm.yaml", 0) == 0, "a swarm error starts with the file name");
  }
  return 0;
}
