// The swarm.yaml node registry (seed §15.2): who the swarm peers are, where to reach them and with which token.
// Tokens are secrets: nothing here ever puts one into a message, and SwarmNode has no printing helper that would.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace rcand::swarm {

inline constexpr std::uint16_t kDefaultSwarmPort = 8000;
inline constexpr const char* kDefaultSwarmFile = "/etc/rcand/swarm.yaml";

struct SwarmNode {
  std::string name;               // MUST
  std::string host;               // MUST: mDNS hostname or IP address
  std::optional<std::string> ip;  // SHOULD: static fallback when `host` does not resolve
  std::uint16_t port = kDefaultSwarmPort;
  std::string token;  // MUST: secret
  std::optional<std::string> rcan, added;
  std::vector<std::string> tags;
  // TLS (the node serves runtime.listen.tls): `ca` set, the node is reached over HTTPS and its certificate must chain
  // to this PEM file and name `host`; `cert`/`key`: this robot's client certificate, for nodes that require one.
  // Relative paths resolve against the swarm file's folder; load_swarm_file checks each can be read.
  std::optional<std::filesystem::path> ca, cert, key;
  int line = 0;  // 1-based line of the entry in the file

  bool has_tag(std::string_view tag) const;
  // "host:port" (the address the registry names, before resolution).
  std::string address() const;
};

struct SwarmRegistry {
  std::filesystem::path source;
  std::vector<SwarmNode> nodes;
  std::vector<std::string> warnings;  // "file:line:column: warning: ..." (unknown keys)

  const SwarmNode* find(std::string_view name) const;
  std::vector<std::string> names() const;
};

// Every error found in the file, one "file:line:column: error: nodes[i].field: message" per line in what().
class SwarmError : public std::runtime_error {
 public:
  explicit SwarmError(std::vector<std::string> errors);
  const std::vector<std::string>& errors() const noexcept { return errors_; }

 private:
  std::vector<std::string> errors_;
};

// Throws SwarmError; a missing or unreadable file is one error "file: error: cannot read: <reason>".
SwarmRegistry load_swarm_file(const std::filesystem::path& file);
// The same from text; `display_name` prefixes the messages.
SwarmRegistry parse_swarm(std::string_view yaml, const std::string& display_name);

}  // namespace rcand::swarm
