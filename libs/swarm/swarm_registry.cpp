#include "libs/swarm/swarm_registry.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <set>
#include <sstream>

#include <boost/asio/ip/address.hpp>

#include "libs/base/closest_match.hpp"

namespace rcand::swarm {
namespace {

constexpr std::array<std::string_view, 11> kNodeKeys{"name", "host",  "ip", "port", "token", "rcan",
                                                     "tags", "added", "ca", "cert", "key"};

std::string position(const std::string& file, const YAML::Mark& mark) {
  if (mark.line < 0) return file;
  return file + ":" + std::to_string(mark.line + 1) + ":" + std::to_string(mark.column + 1);
}

struct Parser {
  // A key the registry does not know, reported as a warning once every node's token is known.
  struct UnknownKey {
    YAML::Mark mark;
    std::string path, key;
    std::optional<std::string> hint;
  };
  std::string file;
  std::vector<std::string> errors;
  std::vector<UnknownKey> unknown_keys;

  void error(const YAML::Mark& mark, const std::string& path, const std::string& message) {
    errors.push_back(position(file, mark) + ": error: " + (path.empty() ? "" : path + ": ") + message);
  }

  // The unknown keys, quoted back, except one that holds a node's token (a mistyped line can put it into a key):
  // no message leaves with a token in it.
  std::vector<std::string> warnings(const std::vector<SwarmNode>& nodes) const {
    std::vector<std::string> out;
    for (const auto& unknown : unknown_keys) {
      const bool holds_token = std::any_of(nodes.begin(), nodes.end(), [&](const SwarmNode& node) {
        return !node.token.empty() && unknown.key.find(node.token) != std::string::npos;
      });
      out.push_back(position(file, unknown.mark) + ": warning: " + unknown.path + ": unknown key " +
                    (holds_token ? "(not quoted: it contains a token)" : "'" + unknown.key + "'") +
                    (unknown.hint ? " (did you mean '" + *unknown.hint + "'?)" : "") + "; ignored");
    }
    return out;
  }

  // A scalar string field. Messages never quote the value (the token is a secret).
  std::optional<std::string> string_field(const YAML::Node& entry, const std::string& path, const char* key, bool required) {
    const YAML::Node value = entry[key];
    if (!value) {
      if (required) error(entry.Mark(), path + "." + key, "missing (a MUST field of §15.2)");
      return std::nullopt;
    }
    if (value.IsNull()) {
      if (required) error(value.Mark(), path + "." + key, "has no value (a MUST field of §15.2)");
      return std::nullopt;
    }
    if (!value.IsScalar()) {
      error(value.Mark(), path + "." + key, "must be a string");
      return std::nullopt;
    }
    std::string text = value.Scalar();
    if (text.empty()) {
      if (required) error(value.Mark(), path + "." + key, "must not be empty");
      return std::nullopt;
    }
    return text;
  }

  std::optional<SwarmNode> node(const YAML::Node& entry, std::size_t index) {
    const std::string path = "nodes[" + std::to_string(index) + "]";
    if (!entry.IsMap()) {
      error(entry.Mark(), path, "must be a mapping with name, host and token");
      return std::nullopt;
    }
    const std::size_t before = errors.size();
    SwarmNode node;
    node.line = entry.Mark().line + 1;
    for (const auto& item : entry) {
      const std::string key = item.first.IsScalar() ? item.first.Scalar() : "";
      if (std::find(kNodeKeys.begin(), kNodeKeys.end(), key) != kNodeKeys.end()) continue;
      std::vector<std::string> known(kNodeKeys.begin(), kNodeKeys.end());
      unknown_keys.push_back({item.first.Mark(), path, key, closest_match(key, known)});
    }
    if (auto name = string_field(entry, path, "name", true)) node.name = *name;
    if (auto host = string_field(entry, path, "host", true)) node.host = *host;
    if (auto token = string_field(entry, path, "token", true)) node.token = *token;
    if (auto ip = string_field(entry, path, "ip", false)) {
      boost::system::error_code ec;
      boost::asio::ip::make_address(*ip, ec);
      if (ec) error(entry["ip"].Mark(), path + ".ip", "'" + *ip + "' is not an IP address");
      else node.ip = *ip;
    }
    if (const YAML::Node port = entry["port"]) {
      int value = 0;
      const bool scalar = port.IsScalar();
      std::string text = scalar ? port.Scalar() : "";
      std::size_t used = 0;
      try {
        value = std::stoi(text, &used);
      } catch (...) {
        used = 0;
      }
      if (!scalar || text.empty() || used != text.size() || value < 1 || value > 65535)
        error(port.Mark(), path + ".port", "must be an integer from 1 to 65535 (default 8000)");
      else node.port = static_cast<std::uint16_t>(value);
    }
    node.rcan = string_field(entry, path, "rcan", false);
    if (auto ca = string_field(entry, path, "ca", false)) node.ca = *ca;
    if (auto cert = string_field(entry, path, "cert", false)) node.cert = *cert;
    if (auto key = string_field(entry, path, "key", false)) node.key = *key;
    if (node.key && !node.cert) error(entry["key"].Mark(), path + ".key", "is given without 'cert' (the client certificate)");
    if (node.cert && !node.ca)
      error(entry["cert"].Mark(), path + ".cert", "needs 'ca' too: a client certificate is only sent over TLS");
    node.added = string_field(entry, path, "added", false);
    if (const YAML::Node tags = entry["tags"]) {
      if (!tags.IsSequence() && !tags.IsNull()) {
        error(tags.Mark(), path + ".tags", "must be a list of strings, e.g. [rover, camera]");
      } else {
        for (std::size_t i = 0; tags.IsSequence() && i < tags.size(); ++i) {
          if (!tags[i].IsScalar() || tags[i].Scalar().empty())
            error(tags[i].Mark(), path + ".tags[" + std::to_string(i) + "]", "must be a non-empty string");
          else node.tags.push_back(tags[i].Scalar());
        }
      }
    }
    if (errors.size() != before) return std::nullopt;
    return node;
  }
};

std::string join_lines(const std::vector<std::string>& lines) {
  std::string text;
  for (const auto& line : lines) text += (text.empty() ? "" : "\n") + line;
  return text;
}

}  // namespace

bool SwarmNode::has_tag(std::string_view tag) const { return std::find(tags.begin(), tags.end(), tag) != tags.end(); }

std::string SwarmNode::address() const {
  const bool v6 = host.find(':') != std::string::npos;
  return (v6 ? "[" + host + "]" : host) + ":" + std::to_string(port);
}

const SwarmNode* SwarmRegistry::find(std::string_view name) const {
  for (const auto& node : nodes)
    if (node.name == name) return &node;
  return nullptr;
}

std::vector<std::string> SwarmRegistry::names() const {
  std::vector<std::string> out;
  for (const auto& node : nodes) out.push_back(node.name);
  return out;
}

SwarmError::SwarmError(std::vector<std::string> errors) : std::runtime_error(join_lines(errors)), errors_(std::move(errors)) {}

SwarmRegistry parse_swarm(std::string_view yaml, const std::string& display_name) {
  Parser parser{display_name, {}, {}};
  YAML::Node root;
  try {
    root = YAML::Load(std::string(yaml));
  } catch (const YAML::Exception& e) {
    parser.error(e.mark, "", "not valid YAML: " + e.msg);
    throw SwarmError(parser.errors);
  }
  SwarmRegistry registry;
  registry.source = display_name;
  if (!root || root.IsNull()) {
    throw SwarmError({display_name + ": error: nodes: the file is empty; it needs a top-level 'nodes:' list"});
  }
  if (!root.IsMap() || !root["nodes"]) {
    parser.error(root.Mark(), "nodes", "missing: the registry is a mapping with a top-level 'nodes:' list (§15.2)");
    throw SwarmError(parser.errors);
  }
  const YAML::Node nodes = root["nodes"];
  if (nodes.IsNull()) return registry;  // `nodes:` with nothing under it: an empty swarm
  if (!nodes.IsSequence()) {
    parser.error(nodes.Mark(), "nodes", "must be a list of node entries");
    throw SwarmError(parser.errors);
  }
  std::set<std::string> seen;
  for (std::size_t i = 0; i < nodes.size(); ++i) {
    auto node = parser.node(nodes[i], i);
    if (!node) continue;
    if (!seen.insert(node->name).second) {
      parser.error(nodes[i]["name"].Mark(), "nodes[" + std::to_string(i) + "].name", "duplicate node name '" + node->name + "'");
      continue;
    }
    registry.nodes.push_back(std::move(*node));
  }
  if (!parser.errors.empty()) throw SwarmError(parser.errors);
  registry.warnings = parser.warnings(registry.nodes);
  return registry;
}

SwarmRegistry load_swarm_file(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) throw SwarmError({file.string() + ": error: cannot read the swarm file: " + std::strerror(errno)});
  std::stringstream text;
  text << in.rdbuf();
  auto registry = parse_swarm(text.str(), file.string());
  registry.source = file;
  // TLS files: relative to the swarm file, and readable now rather than at the first broadcast.
  std::vector<std::string> errors;
  for (auto& node : registry.nodes) {
    const std::pair<std::optional<std::filesystem::path>*, const char*> files[] = {
        {&node.ca, "ca"}, {&node.cert, "cert"}, {&node.key, "key"}};
    for (const auto& [path, key] : files) {
      if (!*path) continue;
      if ((*path)->is_relative()) *path = (file.parent_path() / **path).lexically_normal();
      if (!std::ifstream(**path))
        errors.push_back(file.string() + ":" + std::to_string(node.line) + ": error: node '" + node.name + "' " + key +
                         ": cannot read '" + (*path)->string() + "': " + std::strerror(errno));
    }
  }
  if (!errors.empty()) throw SwarmError(errors);
  return registry;
}

}  // namespace rcand::swarm
