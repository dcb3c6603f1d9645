// Which swarm nodes a broadcast or an rcanctl command addresses: by name and/or tag (seed §15.3 --node, --tag).
#pragma once

#include <string>
#include <variant>
#include <vector>

#include "libs/swarm/swarm_registry.hpp"

namespace rcand::swarm {

struct Selection {
  std::vector<std::string> names;  // any of these (empty: every node)
  std::vector<std::string> tags;   // carrying every one of these (empty: no tag filter)
};

struct SelectionError {
  std::string field;    // "nodes" | "tags"
  std::string message;  // "unknown node 'x'; known nodes: a, b"
};

// The selected nodes in registry order, or an error for an unknown name or a tag no node carries.
std::variant<std::vector<SwarmNode>, SelectionError> select_nodes(const SwarmRegistry& registry, const Selection& selection);

}  // namespace rcand::swarm
