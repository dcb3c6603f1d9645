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

namespace {
// The one piece of a warning that comes from the file: the key quoted after "unknown key '" (the path, position
// and hint are the parser's own text, which a token may happen to match, e.g. "s[0]: unknown key").
std::string_view quoted_key(std::string_view warning) {
  constexpr std::string_view kOpen = "unknown key '";
  const auto open = warning.find(kOpen);
  if (open == std::string_view::npos) return {};
  const auto begin = open + kOpen.size();
  auto end = warning.rfind("' (did you mean '");
  if (end == std::string_view::npos || end < begin) end = warning.rfind("'; ignored");
  if (end == std::string_view::npos || end < begin) return warning.substr(begin);
  return warning.substr(begin, end - begin);
}
}  // namespace

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
        RCAND_FUZZ_CHECK(quoted_key(warning).find(node.token) == std::string_view::npos, "a warning quotes a token");
    }
  } catch (const rcand::swarm::SwarmError& error) {
    RCAND_FUZZ_CHECK(!error.errors().empty(), "a SwarmError carries an error");
    for (const auto& message : error.errors())
      RCAND_FUZZ_CHECK(message.rfind("fuzz-swarm.yaml", 0) == 0, "a swarm error starts with the file name");
  }
  return 0;
}
